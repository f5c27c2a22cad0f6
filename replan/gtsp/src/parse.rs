//! Readers for the GTSP benchmark formats: GTSPLIB/GLNS files (a TSPLIB
//! header, coordinates or an explicit matrix, then `GTSP_SET_SECTION`),
//! GLNS's simple format (`N:` `M:`, set lines starting with the set id, an
//! `N x N` matrix) and Karapetyan's (`N:` `M:` `Symmetric:` `Triangle:`, set
//! lines starting with the set size). Every error names its line.

use std::path::Path;

use super::{Instance, InstanceError};

/// A malformed instance file, with the 1-based line where it went wrong
/// (0 when the problem is the file as a whole).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}{message}", if *line > 0 { format!("line {line}: ") } else { String::new() })]
pub struct ParseError {
    pub line: usize,
    pub message: String,
}

fn fail<T>(line: usize, message: impl Into<String>) -> Result<T, ParseError> {
    Err(ParseError {
        line,
        message: message.into(),
    })
}

impl From<InstanceError> for ParseError {
    fn from(e: InstanceError) -> ParseError {
        ParseError {
            line: 0,
            message: e.to_string(),
        }
    }
}

impl Instance {
    /// Reads an instance file in any of the supported formats, named by the
    /// file's stem (benchmark tables name instances by file).
    pub fn read(path: &Path) -> Result<Instance, ParseError> {
        let text = std::fs::read_to_string(path).or_else(|e| {
            fail(
                0,
                format!("cannot read {}: {e}; check the path", path.display()),
            )
        })?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        Instance::parse(stem, &text)
    }

    /// Parses an instance from text, telling the format from its first line;
    /// an empty `name` takes the file's own NAME.
    pub fn parse(name: &str, text: &str) -> Result<Instance, ParseError> {
        let lines: Vec<Line> = text
            .lines()
            .enumerate()
            .map(|(i, l)| Line {
                number: i + 1,
                text: l.trim(),
            })
            .filter(|l| !l.text.is_empty())
            .collect();
        let Some(first) = lines.first() else {
            return fail(0, "the file is empty; expected a GTSP instance");
        };
        match first.key_value() {
            Some((key, _)) if key.eq_ignore_ascii_case("N") => simple(name, &lines),
            Some(_) => tsplib(name, &lines),
            None if first.section().is_some() => tsplib(name, &lines),
            None => fail(
                first.number,
                "not a GTSP instance: expected a TSPLIB header (`NAME: ...`) or `N: <vertices>`",
            ),
        }
    }
}

#[derive(Clone, Copy)]
struct Line<'a> {
    number: usize,
    text: &'a str,
}

impl<'a> Line<'a> {
    /// `KEY : VALUE` with a non-empty value.
    fn key_value(&self) -> Option<(&'a str, &'a str)> {
        let (key, value) = self.text.split_once(':')?;
        let (key, value) = (key.trim(), value.trim());
        let is_key = !key.is_empty() && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        (is_key && key.starts_with(|c: char| c.is_ascii_alphabetic()) && !value.is_empty())
            .then_some((key, value))
    }

    /// A section keyword alone on its line (`..._SECTION`, optional colon, or EOF).
    fn section(&self) -> Option<&'a str> {
        let word = self.text.trim_end_matches(':').trim();
        let is_section = (word.ends_with("_SECTION") || word == "EOF")
            && word.chars().all(|c| c.is_ascii_uppercase() || c == '_');
        is_section.then_some(word)
    }

    fn tokens(self) -> impl Iterator<Item = Token<'a>> {
        self.text.split_whitespace().map(move |text| Token {
            line: self.number,
            text,
        })
    }
}

#[derive(Clone, Copy)]
struct Token<'a> {
    line: usize,
    text: &'a str,
}

impl Token<'_> {
    fn int(&self, what: &str) -> Result<i64, ParseError> {
        self.text.parse().or_else(|_| {
            fail(
                self.line,
                format!("{what} `{}` is not an integer", self.text),
            )
        })
    }

    fn real(&self, what: &str) -> Result<f64, ParseError> {
        match self.text.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => fail(self.line, format!("{what} `{}` is not a number", self.text)),
        }
    }

    fn weight(&self) -> Result<i32, ParseError> {
        let w = self.int("edge weight")?;
        i32::try_from(w).or_else(|_| {
            fail(
                self.line,
                format!("edge weight {w} is too large (at most {})", i32::MAX),
            )
        })
    }

    /// A 1-based vertex id, returned 0-based.
    fn vertex(&self, n: usize) -> Result<u32, ParseError> {
        match self.int("vertex id")? {
            v if v >= 1 && v as usize <= n => Ok(v as u32 - 1),
            v => fail(
                self.line,
                format!("vertex {v} is out of range: the instance has vertices 1..={n}"),
            ),
        }
    }
}

fn count(value: &str, line: usize, key: &str) -> Result<usize, ParseError> {
    match value.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => fail(
            line,
            format!("{key} must be a positive integer, not `{value}`"),
        ),
    }
}

/// GLNS's simple format or Karapetyan's, which differ in the set lines.
fn simple(name: &str, lines: &[Line]) -> Result<Instance, ParseError> {
    let (mut n, mut m, mut karapetyan) = (None, None, false);
    let mut at = 0;
    while let Some(line) = lines.get(at) {
        let Some((key, value)) = line.key_value() else {
            break;
        };
        match key.to_ascii_uppercase().as_str() {
            "N" => n = Some(count(value, line.number, "N")?),
            "M" => m = Some(count(value, line.number, "M")?),
            "SYMMETRIC" | "TRIANGLE" => karapetyan = true,
            "NAME" | "COMMENT" => {}
            _ => return fail(line.number, format!("unknown header key `{key}`")),
        }
        at += 1;
    }
    let header_end = lines[at.saturating_sub(1)].number;
    let Some(n) = n else {
        return fail(header_end, "the header has no `N: <vertices>` line");
    };
    let Some(m) = m else {
        return fail(header_end, "the header has no `M: <sets>` line");
    };
    let mut sets = Vec::with_capacity(m);
    for s in 0..m {
        let Some(&line) = lines.get(at + s) else {
            return fail(
                header_end,
                format!("the file ends after {s} of the {m} set lines"),
            );
        };
        let tokens: Vec<Token> = line.tokens().collect();
        let lead = tokens[0].int("set line start")?;
        let members = &tokens[1..];
        if karapetyan && lead as usize != members.len() {
            return fail(
                line.number,
                format!(
                    "set {} says it has {lead} vertices but lists {} (Karapetyan format: the size, then the vertices)",
                    s + 1,
                    members.len()
                ),
            );
        }
        if !karapetyan && lead as usize != s + 1 {
            return fail(
                line.number,
                format!(
                    "expected set id {} at the start of the line, found {lead} (GLNS simple format: the set id, then the vertices)",
                    s + 1
                ),
            );
        }
        let set = members
            .iter()
            .map(|t| t.vertex(n))
            .collect::<Result<Vec<_>, _>>()?;
        sets.push(set);
    }
    at += m;
    let tokens: Vec<Token> = lines[at..]
        .iter()
        .filter(|l| l.text != "EOF")
        .flat_map(|l| l.tokens())
        .collect();
    let last = lines.last().map_or(0, |l| l.number);
    let cost = matrix(&tokens, n, Layout::Full, last)?;
    Ok(Instance::new(name, n, cost, sets)?)
}

/// How an explicit matrix lists its weights.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Layout {
    Full,
    UpperRow,
    LowerRow,
    UpperDiagRow,
    LowerDiagRow,
}

impl Layout {
    fn from_name(name: &str) -> Option<Layout> {
        // Column-wise triangles of a symmetric matrix list the same weights
        // as the opposite row-wise triangle.
        Some(match name {
            "FULL_MATRIX" => Layout::Full,
            "UPPER_ROW" | "LOWER_COL" => Layout::UpperRow,
            "LOWER_ROW" | "UPPER_COL" => Layout::LowerRow,
            "UPPER_DIAG_ROW" | "LOWER_DIAG_COL" => Layout::UpperDiagRow,
            "LOWER_DIAG_ROW" | "UPPER_DIAG_COL" => Layout::LowerDiagRow,
            _ => return None,
        })
    }

    /// The (row, column) of each weight in file order.
    fn cells(self, n: usize) -> Box<dyn Iterator<Item = (usize, usize)>> {
        match self {
            Layout::Full => Box::new((0..n).flat_map(move |i| (0..n).map(move |j| (i, j)))),
            Layout::UpperRow => Box::new((0..n).flat_map(move |i| (i + 1..n).map(move |j| (i, j)))),
            Layout::LowerRow => Box::new((0..n).flat_map(|i| (0..i).map(move |j| (i, j)))),
            Layout::UpperDiagRow => Box::new((0..n).flat_map(move |i| (i..n).map(move |j| (i, j)))),
            Layout::LowerDiagRow => Box::new((0..n).flat_map(|i| (0..=i).map(move |j| (i, j)))),
        }
    }

    fn len(self, n: usize) -> usize {
        match self {
            Layout::Full => n * n,
            Layout::UpperRow | Layout::LowerRow => n * (n - 1) / 2,
            Layout::UpperDiagRow | Layout::LowerDiagRow => n * (n + 1) / 2,
        }
    }
}

/// Fills an `n x n` matrix from weight tokens; triangles are mirrored.
fn matrix(
    tokens: &[Token],
    n: usize,
    layout: Layout,
    end_line: usize,
) -> Result<Vec<i32>, ParseError> {
    let want = layout.len(n);
    if tokens.len() < want {
        return fail(
            tokens.last().map_or(end_line, |t| t.line),
            format!(
                "the matrix ends after {} of the {want} weights a {n}-vertex {layout:?} matrix needs",
                tokens.len()
            ),
        );
    }
    if let Some(extra) = tokens.get(want) {
        return fail(
            extra.line,
            format!(
                "`{}` is past the end of the {n}-vertex {layout:?} matrix ({want} weights)",
                extra.text
            ),
        );
    }
    let mut cost = vec![0; n * n];
    for ((i, j), token) in layout.cells(n).zip(tokens) {
        let w = token.weight()?;
        cost[i * n + j] = w;
        if layout != Layout::Full {
            cost[j * n + i] = w;
        }
    }
    Ok(cost)
}

/// How coordinates turn into integer distances (TSPLIB's definitions).
#[derive(Clone, Copy)]
enum Metric {
    Euc2d,
    Ceil2d,
    Man2d,
    Att,
    Geo,
}

impl Metric {
    fn from_name(name: &str) -> Option<Metric> {
        Some(match name {
            "EUC_2D" => Metric::Euc2d,
            "CEIL_2D" => Metric::Ceil2d,
            "MAN_2D" => Metric::Man2d,
            "ATT" => Metric::Att,
            "GEO" => Metric::Geo,
            _ => return None,
        })
    }

    fn distance(self, a: [f64; 2], b: [f64; 2]) -> i32 {
        let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
        let nint = |x: f64| (x + 0.5).floor() as i32;
        match self {
            Metric::Euc2d => nint(dx.hypot(dy)),
            Metric::Ceil2d => dx.hypot(dy).ceil() as i32,
            Metric::Man2d => nint(dx.abs() + dy.abs()),
            Metric::Att => {
                let r = ((dx * dx + dy * dy) / 10.0).sqrt();
                let t = nint(r);
                if (t as f64) < r { t + 1 } else { t }
            }
            Metric::Geo => {
                // TSPLIB's GEO: DDD.MM coordinates, its own value of pi.
                #[allow(clippy::approx_constant)]
                const TSPLIB_PI: f64 = 3.141592;
                let radians = |x: f64| {
                    let degrees = x.trunc();
                    TSPLIB_PI * (degrees + 5.0 * (x - degrees) / 3.0) / 180.0
                };
                let (lat_a, lon_a, lat_b, lon_b) =
                    (radians(a[0]), radians(a[1]), radians(b[0]), radians(b[1]));
                let q1 = (lon_a - lon_b).cos();
                let q2 = (lat_a - lat_b).cos();
                let q3 = (lat_a + lat_b).cos();
                (6378.388 * (0.5 * ((1.0 + q1) * q2 - (1.0 - q1) * q3)).acos() + 1.0) as i32
            }
        }
    }
}

/// GTSPLIB/GLNS: TSPLIB header and sections plus `GTSP_SET_SECTION`.
fn tsplib(file_stem: &str, lines: &[Line]) -> Result<Instance, ParseError> {
    let file = Tsplib::read(file_stem, lines)?;
    let Some((n, _)) = file.n else {
        return fail(0, "the header has no DIMENSION");
    };
    let cost = file.costs(n)?;
    let Some((_, set_line, tokens)) = file.section("GTSP_SET_SECTION") else {
        return fail(
            0,
            "there is no GTSP_SET_SECTION: this is a TSP, not a GTSP instance",
        );
    };
    let sets = set_section(tokens, n, *set_line)?;
    if let Some((m, line)) = file.m
        && m != sets.len()
    {
        return fail(
            line,
            format!(
                "GTSP_SETS says {m} but GTSP_SET_SECTION lists {} sets",
                sets.len()
            ),
        );
    }
    Ok(Instance::new(file.name, n, cost, sets)?)
}

/// A TSPLIB file as read: its header's keys (each with its line) and its
/// sections' tokens.
struct Tsplib<'a> {
    name: String,
    n: Option<(usize, usize)>,
    m: Option<(usize, usize)>,
    weight_type: Option<(String, usize)>,
    weight_format: Option<(String, usize)>,
    sections: Vec<(&'a str, usize, Vec<Token<'a>>)>,
}

impl<'a> Tsplib<'a> {
    fn read(file_stem: &str, lines: &[Line<'a>]) -> Result<Self, ParseError> {
        let mut file = Tsplib {
            name: file_stem.to_string(),
            n: None,
            m: None,
            weight_type: None,
            weight_format: None,
            sections: Vec::new(),
        };
        let mut at = 0;
        while let Some(&line) = lines.get(at) {
            at += 1;
            if let Some(section) = line.section() {
                if section == "EOF" {
                    break;
                }
                let mut tokens = Vec::new();
                while let Some(&data) = lines.get(at) {
                    if data.section().is_some() || data.key_value().is_some() {
                        break;
                    }
                    tokens.extend(data.tokens());
                    at += 1;
                }
                file.sections.push((section, line.number, tokens));
                continue;
            }
            let Some((key, value)) = line.key_value() else {
                return fail(
                    line.number,
                    format!(
                        "expected `KEY : value` or a section name, found `{}`",
                        line.text
                    ),
                );
            };
            let number = line.number;
            match key.to_ascii_uppercase().as_str() {
                "NAME" if file.name.is_empty() => file.name = value.to_string(),
                "DIMENSION" => file.n = Some((count(value, number, "DIMENSION")?, number)),
                "GTSP_SETS" => file.m = Some((count(value, number, "GTSP_SETS")?, number)),
                "EDGE_WEIGHT_TYPE" => file.weight_type = Some((value.to_ascii_uppercase(), number)),
                "EDGE_WEIGHT_FORMAT" => {
                    file.weight_format = Some((value.to_ascii_uppercase(), number))
                }
                _ => {} // TYPE, COMMENT, DISPLAY_DATA_TYPE, NODE_COORD_TYPE: nothing to use
            }
        }
        Ok(file)
    }

    fn section(&self, wanted: &str) -> Option<&(&'a str, usize, Vec<Token<'a>>)> {
        self.sections.iter().find(|(s, _, _)| *s == wanted)
    }

    /// The `n` x `n` cost matrix: given (`EXPLICIT`), or from coordinates
    /// under the edge weight type's metric.
    fn costs(&self, n: usize) -> Result<Vec<i32>, ParseError> {
        let Some((weight_type, type_line)) = &self.weight_type else {
            return fail(0, "the header has no EDGE_WEIGHT_TYPE");
        };
        if weight_type == "EXPLICIT" {
            let Some((format, format_line)) = &self.weight_format else {
                return fail(
                    *type_line,
                    "EDGE_WEIGHT_TYPE is EXPLICIT but there is no EDGE_WEIGHT_FORMAT",
                );
            };
            let Some(layout) = Layout::from_name(format) else {
                return fail(
                    *format_line,
                    format!(
                        "EDGE_WEIGHT_FORMAT {format} is not supported; use FULL_MATRIX, UPPER_ROW, LOWER_ROW, UPPER_DIAG_ROW or LOWER_DIAG_ROW"
                    ),
                );
            };
            let Some((_, line, tokens)) = self.section("EDGE_WEIGHT_SECTION") else {
                return fail(
                    0,
                    "EDGE_WEIGHT_TYPE is EXPLICIT but there is no EDGE_WEIGHT_SECTION",
                );
            };
            return matrix(tokens, n, layout, *line);
        }
        let Some(metric) = Metric::from_name(weight_type) else {
            return fail(
                *type_line,
                format!(
                    "EDGE_WEIGHT_TYPE {weight_type} is not supported; use EXPLICIT, EUC_2D, CEIL_2D, MAN_2D, ATT or GEO"
                ),
            );
        };
        let Some((_, line, tokens)) = self.section("NODE_COORD_SECTION") else {
            return fail(
                0,
                format!("EDGE_WEIGHT_TYPE is {weight_type} but there is no NODE_COORD_SECTION"),
            );
        };
        let coords = coordinates(tokens, n, *line)?;
        let mut cost = vec![0; n * n];
        for a in 0..n {
            for b in 0..n {
                if a != b {
                    cost[a * n + b] = metric.distance(coords[a], coords[b]);
                }
            }
        }
        Ok(cost)
    }
}

/// `id x y` for every vertex, in any order.
fn coordinates(
    tokens: &[Token],
    n: usize,
    section_line: usize,
) -> Result<Vec<[f64; 2]>, ParseError> {
    let mut coords = vec![None; n];
    let rows = tokens.chunk_by(|a, b| a.line == b.line);
    for row in rows {
        let [id, x, y] = row else {
            return fail(row[0].line, "a coordinate line is `id x y`");
        };
        let v = id.vertex(n)? as usize;
        if coords[v].is_some() {
            return fail(id.line, format!("vertex {} has coordinates twice", v + 1));
        }
        coords[v] = Some([x.real("x")?, y.real("y")?]);
    }
    match coords.iter().position(Option::is_none) {
        Some(v) => fail(section_line, format!("vertex {} has no coordinates", v + 1)),
        None => Ok(coords.into_iter().flatten().collect()),
    }
}

/// `set_id v v ... -1` for every set.
fn set_section(
    tokens: &[Token],
    n: usize,
    section_line: usize,
) -> Result<Vec<Vec<u32>>, ParseError> {
    let mut sets = Vec::new();
    let mut tokens = tokens.iter();
    while let Some(id) = tokens.next() {
        let expected = sets.len() as i64 + 1;
        if id.int("set id")? != expected {
            return fail(
                id.line,
                format!("expected set id {expected}, found `{}`", id.text),
            );
        }
        let mut set = Vec::new();
        loop {
            let Some(token) = tokens.next() else {
                return fail(id.line, format!("set {expected} does not end with -1"));
            };
            if token.int("vertex id")? == -1 {
                break;
            }
            set.push(token.vertex(n)?);
        }
        sets.push(set);
    }
    if sets.is_empty() {
        return fail(section_line, "GTSP_SET_SECTION lists no sets");
    }
    Ok(sets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_and_full_matrices_agree() {
        // The same symmetric 4-vertex instance written five ways.
        let full = [0, 1, 2, 3, 1, 0, 4, 5, 2, 4, 0, 6, 3, 5, 6, 0];
        let layouts = [
            ("FULL_MATRIX", "0 1 2 3\n1 0 4 5\n2 4 0 6\n3 5 6 0"),
            ("UPPER_ROW", "1 2 3\n4 5\n6"),
            ("LOWER_ROW", "1\n2 4\n3 5 6"),
            ("UPPER_DIAG_ROW", "0 1 2 3 0 4 5 0 6 0"),
            ("LOWER_DIAG_ROW", "0\n1 0\n2 4 0\n3 5 6 0"),
        ];
        for (format, weights) in layouts {
            let text = format!(
                "NAME: t\nTYPE: GTSP\nDIMENSION: 4\nGTSP_SETS: 2\nEDGE_WEIGHT_TYPE: EXPLICIT\nEDGE_WEIGHT_FORMAT: {format}\nEDGE_WEIGHT_SECTION\n{weights}\nGTSP_SET_SECTION:\n1 1 2 -1\n2 3 4 -1\nEOF\n"
            );
            let inst = Instance::parse("t", &text).unwrap_or_else(|e| panic!("{format}: {e}"));
            for a in 0..4u32 {
                for b in 0..4u32 {
                    if a != b {
                        assert_eq!(
                            inst.cost(a, b),
                            full[(a * 4 + b) as usize],
                            "{format} {a}->{b}"
                        );
                    }
                }
            }
            assert!(inst.is_symmetric());
        }
    }

    #[test]
    fn euc_2d_rounds_to_nearest_integer() {
        let text = "NAME : e\nTYPE : GTSP\nDIMENSION : 3\nGTSP_SETS : 2\nEDGE_WEIGHT_TYPE : EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 3 4\n3 1 1.5\nGTSP_SET_SECTION\n1 1 -1\n2 2 3 -1\nEOF\n";
        let inst = Instance::parse("e", text).unwrap();
        assert_eq!(inst.cost(0, 1), 5);
        assert_eq!(inst.cost(0, 2), 2); // 1.803 rounds up
        assert_eq!(inst.cost(1, 2), 3); // 3.202 rounds down
        assert_eq!(inst.sets(), &[vec![0], vec![1, 2]]);
    }

    #[test]
    fn simple_formats_tell_set_ids_from_set_sizes() {
        let glns = "N: 4\nM: 2\n1 1 2\n2 3 4\n0 1 2 3\n4 0 5 6\n7 8 0 9\n1 2 3 0\n";
        let inst = Instance::parse("g", glns).unwrap();
        assert_eq!(inst.sets(), &[vec![0, 1], vec![2, 3]]);
        assert!(!inst.is_symmetric());
        assert_eq!(inst.cost(1, 0), 4);
        let karapetyan = "N: 4\nM: 2\nSymmetric: false\nTriangle: false\n1 3\n3 1 2 4\n0 1 2 3\n4 0 5 6\n7 8 0 9\n1 2 3 0\n";
        let inst = Instance::parse("k", karapetyan).unwrap();
        assert_eq!(inst.sets(), &[vec![2], vec![0, 1, 3]]);
    }

    #[test]
    fn errors_name_the_line() {
        let cases = [
            ("N: 4\nM: 2\n1 1 2\n3 3 4\n", 4, "expected set id 2"),
            (
                "N: 2\nM: 1\nSymmetric: true\n3 1 2\n0 1\n1 0\n",
                4,
                "says it has 3",
            ),
            ("N: 2\nM: 1\n1 1 2\n0 1\n1 x\n", 5, "not an integer"),
            ("N: 2\nM: 1\n1 1 2\n0 1\n1\n", 5, "ends after 3 of the 4"),
            ("N: 2\nM: 1\n1 1 5\n0 1\n1 0\n", 3, "out of range"),
            (
                "NAME: x\nDIMENSION: 2\nEDGE_WEIGHT_TYPE: EUC_3D\nNODE_COORD_SECTION\n1 0 0\n2 1 1\n",
                3,
                "not supported",
            ),
            (
                "NAME: x\nDIMENSION: 2\nEDGE_WEIGHT_TYPE: EUC_2D\nNODE_COORD_SECTION\n1 0 0\n2 1 1\nGTSP_SET_SECTION\n1 1 2\n",
                8,
                "does not end with -1",
            ),
            ("hello\n", 1, "not a GTSP instance"),
        ];
        for (text, line, words) in cases {
            let e = Instance::parse("bad", text).unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(e.message.contains(words), "{text:?}: {e}");
        }
        let shared = "N: 2\nM: 2\n1 1\n2 1\n0 1\n1 0\n";
        let e = Instance::parse("bad", shared).unwrap_err();
        assert!(e.message.contains("sets must be disjoint"), "{e}");
    }
}
