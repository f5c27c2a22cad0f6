//! Waypoint paths as CSV: one row `X,Y,Z,Yaw` per waypoint (metres in the
//! world frame, yaw in radians unless told otherwise), a header line
//! optional, `#` comments and blank lines ignored. GATSBI writes its
//! inspection paths this way. A header may name more columns after those
//! four; of them `GimbalPitch` (degrees, negative looking down, as DJI
//! gives it) sets the camera's pitch, and `Point` keeps only the rows that
//! are `waypoint`s (not `home` or `transit`), as `replan.csv` writes them.

use csv::{ReaderBuilder, StringRecord, Trim};
use polars::prelude::{DataType, PolarsResult};

use super::{PathPoint, PointKind, YawUnit};
use crate::setting::inputs;
use crate::table::Row;

crate::table! {
    /// One row of `replan.csv`: a point of a sortie's path, home to home.
    /// Its first four columns are GATSBI's inspection path.
    pub struct PathRow {
        /// World frame (the SLAM map's), z up, metres.
        x: f64 as X,
        y: f64 as Y,
        z: f64 as Z,
        /// Radians, counter-clockwise from the x axis (REP 103): the yaw of
        /// the waypoint being flown to.
        yaw: f64 as Yaw,
        /// Degrees, negative looking down (as DJI gives it).
        gimbal_pitch_deg: f64 as GimbalPitch,
        /// The sortie, from 1.
        sortie: u32 as Sortie,
        /// What the point is: where the sortie takes off and lands, on the
        /// collision-free path, or a waypoint to hover and shoot at.
        point: PointKind as Point,
    }
}

/// The columns every waypoint path has: GATSBI's `X,Y,Z,Yaw`.
const COLUMNS: usize = 4;

/// A path's rows as CSV, each number as Rust writes it (the shortest text
/// that reads back as the same number, never an exponent), as GATSBI's
/// paths are; after `comments` (each line starting with `#`).
pub fn path_csv(comments: &str, rows: &[PathRow]) -> PolarsResult<String> {
    let table = PathRow::frame(rows)?;
    let mut text = comments.to_string();
    text += &PathRow::column_names().join(",");
    text.push('\n');
    let cells = table
        .columns()
        .iter()
        .map(|c| cell_texts(c.as_materialized_series()))
        .collect::<PolarsResult<Vec<_>>>()?;
    for row in 0..table.height() {
        let line: Vec<&str> = cells.iter().map(|c| c[row].as_str()).collect();
        text += &line.join(",");
        text.push('\n');
    }
    Ok(text)
}

/// A column's values as `path_csv` writes them.
fn cell_texts(column: &polars::prelude::Series) -> PolarsResult<Vec<String>> {
    let text = |v: Option<String>| v.unwrap_or_default();
    Ok(match column.dtype() {
        DataType::Float64 => column
            .f64()?
            .iter()
            .map(|v| text(v.map(|v| v.to_string())))
            .collect(),
        DataType::UInt32 => column
            .u32()?
            .iter()
            .map(|v| text(v.map(|v| v.to_string())))
            .collect(),
        _ => column
            .str()?
            .iter()
            .map(|v| text(v.map(str::to_string)))
            .collect(),
    })
}

/// The waypoints of a path, or a one-line error naming the line and column.
pub fn parse(text: &str, yaw: YawUnit) -> Result<Vec<PathPoint>, String> {
    let mut reader = ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut points = Vec::new();
    let mut columns = COLUMNS;
    let mut extra = Extra::default();
    for (i, record) in reader.records().enumerate() {
        let record = record.map_err(|e| format!("not a CSV file: {e}"))?;
        let line = record.position().map_or(0, csv::Position::line);
        if i == 0 && is_header(&record) {
            check_header(&record, line)?;
            columns = record.len();
            extra = Extra::of(&record);
            continue;
        }
        // Before any column is read: the header's columns past the four
        // may be missing from a short row.
        check_width(&record, line, columns)?;
        if extra
            .point
            .is_some_and(|k| &record[k] != PointKind::Waypoint.as_str())
        {
            continue;
        }
        let mut p = point(&record, line, yaw)?;
        if let Some(k) = extra.gimbal_pitch {
            let pitch = number(&record[k], line, k, "GimbalPitch, degrees")?;
            p.gimbal_pitch = Some(-pitch.to_radians());
        }
        points.push(p);
    }
    if points.is_empty() {
        return Err("the path has no waypoints; give one `X,Y,Z,Yaw` row per waypoint".into());
    }
    Ok(points)
}

/// Where the optional columns a header names are.
#[derive(Debug, Default)]
struct Extra {
    gimbal_pitch: Option<usize>,
    point: Option<usize>,
}

impl Extra {
    fn of(header: &StringRecord) -> Self {
        let names = PathRow::column_names();
        let find = |name: &str| {
            header
                .iter()
                .skip(COLUMNS)
                .position(|f| f.eq_ignore_ascii_case(name))
                .map(|k| k + COLUMNS)
        };
        // PathRow's `GimbalPitch` and `Point`, in any place after the four.
        Self {
            gimbal_pitch: find(&names[4]),
            point: find(&names[6]),
        }
    }
}

/// A first row that is not all numbers names the columns.
fn is_header(record: &StringRecord) -> bool {
    record.iter().any(|field| field.parse::<f64>().is_err())
}

fn check_header(record: &StringRecord, line: u64) -> Result<(), String> {
    let named = record.iter().take(COLUMNS).map(str::to_ascii_lowercase);
    let declared = PathRow::column_names().into_iter().take(COLUMNS);
    if !named.eq(declared.map(|n| n.to_ascii_lowercase())) {
        return Err(format!(
            "line {line}: the header names the columns {}; a waypoint path has the columns X,Y,Z,Yaw in this order",
            shown(&record.iter().collect::<Vec<_>>().join(","))
        ));
    }
    Ok(())
}

/// A row has the path's `columns` columns, or an error naming its line.
fn check_width(record: &StringRecord, line: u64, columns: usize) -> Result<(), String> {
    if record.len() != columns {
        return Err(format!(
            "line {line}: {} columns where a waypoint has {columns} (X,Y,Z,Yaw{})",
            record.len(),
            if columns > COLUMNS {
                " and the header's others"
            } else {
                ""
            }
        ));
    }
    Ok(())
}

/// A row of a path whose width is checked, the first four `X,Y,Z,Yaw`.
fn point(record: &StringRecord, line: u64, yaw_unit: YawUnit) -> Result<PathPoint, String> {
    let mut values = [0.0; 4];
    for (column, (field, value)) in record.iter().take(4).zip(&mut values).enumerate() {
        *value = number(field, line, column, &PathRow::column_names()[column])?;
    }
    let [x, y, z, yaw] = values;
    let yaw = match yaw_unit {
        YawUnit::Radians if yaw.abs() > 2.0 * std::f64::consts::TAU => {
            return Err(format!(
                "line {line}, column 4: a yaw of {yaw} radians is more than two turns; if the path's yaws are in degrees, pass {}",
                inputs::YAW_DEGREES
            ));
        }
        YawUnit::Radians => yaw,
        YawUnit::Degrees => yaw.to_radians(),
    };
    Ok(PathPoint {
        position: [x, y, z],
        yaw,
        gimbal_pitch: None,
    })
}

/// The finite number in `field` (column `column` from 0, named `what`), or
/// an error naming its line and column.
fn number(field: &str, line: u64, column: usize, what: &str) -> Result<f64, String> {
    field
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            format!(
                "line {line}, column {}: {} is not a finite number ({what})",
                column + 1,
                shown(field)
            )
        })
}

/// A field as an error quotes it: escaped (one line) and at most 40
/// characters.
fn shown(field: &str) -> String {
    const MAX: usize = 40;
    match field.char_indices().nth(MAX) {
        Some((end, _)) => format!("{:?}...", &field[..end]),
        None => format!("{field:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_with_or_without_a_header_and_comments_read_as_waypoints() {
        let with = "X,Y,Z,Yaw\n# first\n1,2,3,0.5\n\n 4 , 5 , 6 , -1.5\n";
        let without = "1,2,3,0.5\n4,5,6,-1.5";
        for text in [with, without] {
            let path = parse(text, YawUnit::Radians).unwrap();
            assert_eq!(path.len(), 2);
            assert_eq!(path[1].position, [4.0, 5.0, 6.0]);
            assert_eq!(path[1].yaw, -1.5);
        }
        let degrees = parse("0,0,0,90", YawUnit::Degrees).unwrap();
        // replan.csv's own columns after the four: its waypoints with their
        // gimbal pitch (30 degrees down), not home.
        let replan = "# frame: map\nX,Y,Z,Yaw,GimbalPitch,Sortie,Point\n0,0,1,0.1,0.0,1,home\n1,0,1,0.5,-30.0,1,waypoint\n";
        let flown = parse(replan, YawUnit::Radians).unwrap();
        assert_eq!(flown.len(), 1);
        assert_eq!(flown[0].yaw, 0.5);
        assert!((flown[0].gimbal_pitch.unwrap() - 30f64.to_radians()).abs() < 1e-12);
        assert_eq!(path_without_pitch(with), None);
        assert!((degrees[0].yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    }

    #[test]
    fn a_written_path_reads_back_as_its_waypoints() {
        let row = |x: f64, point| PathRow {
            x,
            y: 0.0,
            z: 2.5,
            yaw: 0.5,
            gimbal_pitch_deg: -30.0,
            sortie: 1,
            point,
        };
        let rows = [row(0.0, PointKind::Home), row(1.0e-7, PointKind::Waypoint)];
        let text = path_csv("# frame: map\n", &rows).unwrap();
        // Numbers as GATSBI's paths give them: no exponent, no trailing `.0`.
        assert_eq!(
            text,
            "# frame: map\nX,Y,Z,Yaw,GimbalPitch,Sortie,Point\n0,0,2.5,0.5,-30,1,home\n0.0000001,0,2.5,0.5,-30,1,waypoint\n"
        );
        let flown = parse(&text, YawUnit::Radians).unwrap();
        assert_eq!(flown.len(), 1);
        assert_eq!(flown[0].position, [1.0e-7, 0.0, 2.5]);
        assert!((flown[0].gimbal_pitch.unwrap() - 30f64.to_radians()).abs() < 1e-12);
    }

    #[test]
    fn a_row_shorter_than_its_header_is_named_not_read_past_its_end() {
        // Found by the `plan` fuzz target: a row without the header's
        // `Point` column was indexed past its end.
        let text = "X,Y,Z,Yaw,GimbalPitch,Sortie,Point\n0,0,1,0,0,1,home\n1,2,3,0\n";
        let e = parse(text, YawUnit::Radians).unwrap_err();
        assert!(
            e.starts_with("line 3: 4 columns where a waypoint has 7"),
            "{e}"
        );
    }

    fn path_without_pitch(text: &str) -> Option<f64> {
        parse(text, YawUnit::Radians).unwrap()[0].gimbal_pitch
    }

    #[test]
    fn a_malformed_path_names_its_line_and_column() {
        let cases = [
            ("X,Y,Z,Yaw\n1,2,3,0\n1,2,x,0\n", "line 3, column 3: \"x\""),
            ("1,2,3\n", "line 1: 3 columns"),
            ("1,2,3,0\n1,2,3,4,5\n", "line 2: 5 columns"),
            (
                "x,y,yaw,z\n1,2,3,0\n",
                "line 1: the header names the columns \"x,y,yaw,z\"",
            ),
            ("1,2,3,NaN\n", "line 1, column 4: \"NaN\""),
            ("0,0,0,90\n", "--yaw-degrees"),
            ("X,Y,Z,Yaw\n# nothing\n", "no waypoints"),
            (
                "X,Y,Z,Yaw,GimbalPitch\n1,2,3,0,down\n",
                "line 2, column 5: \"down\" is not a finite number (GimbalPitch",
            ),
            ("", "no waypoints"),
        ];
        for (text, want) in cases {
            let err = parse(text, YawUnit::Radians).unwrap_err();
            assert!(err.contains(want), "{text:?}: {err}");
        }
    }
}
