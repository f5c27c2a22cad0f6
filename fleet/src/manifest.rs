//! The batch manifest: one row per flight, in TOML or CSV.
//!
//! TOML:
//!
//! ```toml
//! [defaults]                 # optional; any file column but `flight`
//! model = "models/crack.onnx"
//! config = "postflight.toml"
//!
//! [[flight]]
//! structure = "bridge-a"
//! date = 2026-05-01
//! flight = "flights/bridge-a-may.mcap"
//! plan = "plans/bridge-a.json"
//! ```
//!
//! CSV: a header naming the columns (`structure,date,flight,plan`, in any
//! order; empty cells are absent). Relative paths are relative to the
//! manifest's directory. A flight's run directory is
//! `FLEET_DIR/<structure>/<name or date>/`.
//!
//! A flight with `shards = N` (N > 1) is N tasks, each one share of its
//! detect (the stages before detect run once, by the first task there; the
//! later ones by the task finishing the last share); any other flight is
//! one task. Tasks are numbered from 0 in manifest order, a flight's
//! shares in order: `postflight batch task --index`, the Slurm array index
//! and the Kubernetes completion index.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use jiff::civil::Date;
use serde::{Deserialize, Deserializer};

use postflight_core::outputs::detect::Shard;

use crate::error::Error;

/// A manifest, read and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest {
    /// Where it was read from, absolute.
    pub path: PathBuf,
    pub flights: Vec<FlightEntry>,
}

/// One flight of the fleet.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightEntry {
    /// Its index in the manifest, from 0 (the Slurm array and Kubernetes
    /// completion index).
    pub index: usize,
    /// The structure's id: a directory name and Hive partition value.
    pub structure: String,
    pub date: Option<Date>,
    /// Tells flights of one structure apart when the date does not.
    pub name: Option<String>,
    pub flight: PathBuf,
    pub map: Option<PathBuf>,
    pub plan: Option<PathBuf>,
    /// The yaws of a waypoint-path plan are in degrees.
    pub yaw_degrees: bool,
    /// The structure to inspect instead of the plan's target voxels: boxes
    /// (`.json`), a segmented cloud (`.ply`, `.pcd`) or OctoMap (`.bt`, `.ot`).
    pub targets: Option<PathBuf>,
    pub model: Option<PathBuf>,
    pub config: Option<PathBuf>,
    /// Its detect split into this many shares, a task each (1: one task
    /// runs the whole flight).
    pub shards: u32,
}

/// One task of a manifest: a flight, or one share of a flight's detect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Task {
    /// Its number, from 0 (see the module's docs).
    pub index: usize,
    /// Its flight's index in the manifest.
    pub flight: usize,
    /// Its share of the flight's detect; `None`: the whole flight.
    pub share: Option<Shard>,
}

impl FlightEntry {
    /// Its run's name within the structure: the name, else the date.
    pub fn run_name(&self) -> String {
        self.name
            .clone()
            .or_else(|| self.date.map(|d| d.to_string()))
            .expect("a checked entry has a name or a date")
    }

    /// `<structure>/<name or date>`, how messages and tables name the flight.
    pub fn label(&self) -> String {
        format!("{}/{}", self.structure, self.run_name())
    }

    /// Its run directory in `fleet`.
    pub fn run_dir(&self, fleet: &Path) -> PathBuf {
        fleet.join(&self.structure).join(self.run_name())
    }
}

#[cfg(test)]
impl FlightEntry {
    /// A flight of structure `b` named `n`, for tests.
    pub(crate) fn example(index: usize) -> Self {
        Self {
            index,
            structure: "b".into(),
            date: None,
            name: Some("n".into()),
            flight: "f.mcap".into(),
            map: None,
            plan: None,
            yaw_degrees: false,
            targets: None,
            model: None,
            config: None,
            shards: 1,
        }
    }
}

impl Manifest {
    /// Read a manifest: `.toml`, else CSV.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let path = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
        let text = std::fs::read_to_string(&path).map_err(|cause| Error::Manifest {
            path: path.clone(),
            why: format!("cannot read it ({cause}); check the path"),
        })?;
        let base = path.parent().unwrap_or(Path::new("/")).to_owned();
        let is_toml = path.extension().is_some_and(|e| e == "toml");
        let rows = if is_toml {
            toml_rows(&text)
        } else {
            csv_rows(&text)
        };
        let flights =
            rows.and_then(|rows| entries(rows, &base))
                .map_err(|why| Error::Manifest {
                    path: path.clone(),
                    why,
                })?;
        Ok(Self { path, flights })
    }

    /// Every task, in order: a flight's, or each share of its detect.
    pub fn tasks(&self) -> Vec<Task> {
        let mut tasks = Vec::new();
        for flight in &self.flights {
            let shares: Vec<Option<Shard>> = match flight.shards {
                0 | 1 => vec![None],
                count => (1..=count)
                    .map(|index| Some(Shard { index, count }))
                    .collect(),
            };
            for share in shares {
                tasks.push(Task {
                    index: tasks.len(),
                    flight: flight.index,
                    share,
                });
            }
        }
        tasks
    }

    /// The task at `index`, or an error naming the valid range.
    pub fn task(&self, index: usize) -> Result<Task, Error> {
        let tasks = self.tasks();
        tasks.get(index).copied().ok_or_else(|| Error::Manifest {
            path: self.path.clone(),
            why: format!(
                "has {} tasks (a flight each, or a share of a flight's detect), indexed 0 to {}; there is no task {index}",
                tasks.len(),
                tasks.len().saturating_sub(1)
            ),
        })
    }
}

/// A row as written, before paths are resolved and names checked.
#[derive(Debug, Default, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct Row {
    structure: Option<String>,
    flight: Option<PathBuf>,
    date: Option<DateCell>,
    name: Option<String>,
    map: Option<PathBuf>,
    plan: Option<PathBuf>,
    yaw: Option<YawName>,
    targets: Option<PathBuf>,
    model: Option<PathBuf>,
    config: Option<PathBuf>,
    shards: Option<u32>,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
enum YawName {
    Radians,
    Degrees,
}

impl Row {
    /// The row, each file it leaves out taken from `defaults`.
    fn or(self, d: Row) -> Row {
        Row {
            map: self.map.or(d.map),
            plan: self.plan.or(d.plan),
            yaw: self.yaw.or(d.yaw),
            targets: self.targets.or(d.targets),
            model: self.model.or(d.model),
            config: self.config.or(d.config),
            shards: self.shards.or(d.shards),
            ..self
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TomlManifest {
    /// Files every flight shares (a flight's own row wins).
    #[serde(default)]
    defaults: Row,
    #[serde(default)]
    flight: Vec<Row>,
}

/// Rows of a TOML manifest, each with where it is and the defaults applied.
fn toml_rows(text: &str) -> Result<Vec<(String, Row)>, String> {
    let manifest: TomlManifest = toml::from_str(text).map_err(|e| {
        format!(
            "not a valid manifest: {}; see `postflight batch run --help` for the columns",
            e.message()
        )
    })?;
    let d = &manifest.defaults;
    if d.structure.is_some() || d.flight.is_some() || d.date.is_some() || d.name.is_some() {
        return Err("[defaults] gives a flight's own column; it may give map, plan, yaw, targets, model, config and shards".into());
    }
    Ok(manifest
        .flight
        .into_iter()
        .enumerate()
        .map(|(i, row)| (format!("flight {}", i + 1), row.or(d.clone())))
        .collect())
}

/// Rows of a CSV manifest, each with its line.
fn csv_rows(text: &str) -> Result<Vec<(String, Row)>, String> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    reader
        .deserialize::<Row>()
        .map(|row| {
            row.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                let why = match e.kind() {
                    csv::ErrorKind::Deserialize { err, .. } => err.to_string(),
                    _ => e.to_string(),
                };
                format!("line {line}: {why}; the columns are structure, flight, date, name, map, plan, yaw, targets, model, config, shards")
            })
        })
        .enumerate()
        .map(|(i, row)| row.map(|row| (format!("row {}", i + 1), row)))
        .collect()
}

/// Checked entries: each with a structure, a flight and a name or date, no
/// two sharing a run directory.
fn entries(rows: Vec<(String, Row)>, base: &Path) -> Result<Vec<FlightEntry>, String> {
    if rows.is_empty() {
        return Err("lists no flights; add one row per flight".into());
    }
    let mut by_run: HashMap<String, String> = HashMap::new();
    let mut flights = Vec::with_capacity(rows.len());
    for (index, (source, row)) in rows.into_iter().enumerate() {
        let entry = entry(index, row, base).map_err(|why| format!("{source}: {why}"))?;
        if let Some(other) = by_run.insert(entry.label(), source.clone()) {
            return Err(format!(
                "{other} and {source} both go to {}; give one of them a `name`",
                entry.label()
            ));
        }
        flights.push(entry);
    }
    Ok(flights)
}

fn entry(index: usize, row: Row, base: &Path) -> Result<FlightEntry, String> {
    let structure = row
        .structure
        .ok_or("no `structure`; give the structure's id")?;
    check_id("structure", &structure)?;
    check_not_reserved(&structure)?;
    if let Some(name) = &row.name {
        check_id("name", name)?;
    }
    let date = row.date.map(|d| d.0);
    if date.is_none() && row.name.is_none() {
        return Err("neither `date` nor `name`; give the flight's date (YYYY-MM-DD)".into());
    }
    let flight = row.flight.ok_or("no `flight`; give the flight recording")?;
    let shards = row.shards.unwrap_or(1);
    if !(1..=MAX_SHARDS).contains(&shards) {
        return Err(format!(
            "shards {shards} is not a number of shares of the flight's detect; give 1 to {MAX_SHARDS}"
        ));
    }
    let resolve = |p: Option<PathBuf>| p.map(|p| base.join(p));
    Ok(FlightEntry {
        index,
        structure,
        date,
        name: row.name,
        flight: base.join(flight),
        map: resolve(row.map),
        plan: resolve(row.plan),
        yaw_degrees: row.yaw == Some(YawName::Degrees),
        targets: resolve(row.targets),
        model: resolve(row.model),
        config: resolve(row.config),
        shards,
    })
}

/// The most shares a flight's detect is split into (as `--shard` takes).
const MAX_SHARDS: u32 = 10_000;

/// Ids become directory names and Hive partition values: letters, digits,
/// `.`, `_` and `-`, not starting with a dot.
fn check_id(column: &str, id: &str) -> Result<(), String> {
    let allowed = |c: char| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-');
    if id.is_empty() || id.starts_with('.') || !id.chars().all(allowed) {
        return Err(format!(
            "{column} '{id}' is not a valid id; use letters, digits, '.', '_' and '-' (not starting with '.')"
        ));
    }
    Ok(())
}

/// The fleet directory's own directories (the tables, the Slurm job), which
/// no structure's runs may share.
pub const RESERVED: [&str; 2] = [crate::tables::files::DIR, crate::slurm::SLURM_DIR];

fn check_not_reserved(structure: &str) -> Result<(), String> {
    if RESERVED.contains(&structure) {
        return Err(format!(
            "structure '{structure}' is reserved (FLEET_DIR/{} holds the fleet's tables, FLEET_DIR/{} the Slurm job); give the structure another id",
            RESERVED[0], RESERVED[1]
        ));
    }
    Ok(())
}

/// A date cell: `YYYY-MM-DD` as text, or a TOML date.
#[derive(Debug, Clone, Copy)]
struct DateCell(Date);

impl<'de> Deserialize<'de> for DateCell {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = DateCell;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a date YYYY-MM-DD")
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<DateCell, E> {
                s.parse::<Date>()
                    .map(DateCell)
                    .map_err(|_| E::custom(format!("date '{s}' is not a date YYYY-MM-DD")))
            }
            // A bare TOML date arrives as a one-entry map of its text.
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<DateCell, A::Error> {
                let (_, text): (String, String) = map
                    .next_entry()?
                    .ok_or_else(|| serde::de::Error::custom("an empty date"))?;
                self.visit_str(&text)
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(name: &str, text: &str) -> Result<Manifest, Error> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        Manifest::load(&path)
    }

    #[test]
    fn a_toml_manifest_gives_defaults_to_every_flight_and_resolves_paths_beside_it() {
        let m = load(
            "fleet.toml",
            r#"
[defaults]
model = "crack.onnx"

[[flight]]
structure = "bridge-a"
date = 2026-05-01
flight = "a.mcap"

[[flight]]
structure = "bridge-a"
date = "2026-05-01"
name = "afternoon"
flight = "/data/b.mcap"
model = "other.onnx"
yaw = "degrees"
"#,
        )
        .unwrap();
        let base = m.path.parent().unwrap();
        assert_eq!(m.flights.len(), 2);
        let [a, b] = &m.flights[..] else { panic!() };
        assert_eq!(a.run_name(), "2026-05-01");
        assert_eq!(a.flight, base.join("a.mcap"));
        assert_eq!(a.model.as_deref(), Some(base.join("crack.onnx").as_path()));
        assert!(!a.yaw_degrees);
        assert_eq!(b.label(), "bridge-a/afternoon");
        assert_eq!(b.flight, PathBuf::from("/data/b.mcap"));
        assert_eq!(b.model.as_deref(), Some(base.join("other.onnx").as_path()));
        assert!(b.yaw_degrees);
        assert_eq!(b.index, 1);
    }

    #[test]
    fn a_csv_manifest_reads_columns_in_any_order_and_empty_cells_as_absent() {
        let m = load(
            "fleet.csv",
            "flight,structure,date,plan\n# a comment\na.mcap,tower-1,2026-03-02,\nb.mcap, silo ,2026-03-03,p.json\n",
        )
        .unwrap();
        assert_eq!(m.flights[0].plan, None);
        assert_eq!(m.flights[1].structure, "silo");
        assert!(m.flights[1].plan.as_ref().unwrap().ends_with("p.json"));
    }

    #[test]
    fn manifest_errors_name_the_row_and_what_to_do() {
        let cases = [
            (
                "m.csv",
                "structure,flight\nb,a.mcap\n",
                "row 1: neither `date` nor `name`",
            ),
            (
                "m.csv",
                "structure,flight,colour\nb,a.mcap,red\n",
                "unknown field `colour`",
            ),
            (
                "m.csv",
                "structure,flight,date\nb,a.mcap,May 1\n",
                "date 'May 1' is not a date",
            ),
            (
                "m.csv",
                "structure,flight,date\n../x,a.mcap,2026-01-01\n",
                "structure '../x' is not a valid id",
            ),
            (
                "m.csv",
                "structure,flight,date\nb,a.mcap,2026-01-01\nb,c.mcap,2026-01-01\n",
                "row 1 and row 2 both go to b/2026-01-01; give one of them a `name`",
            ),
            ("m.csv", "structure,flight,date\n", "lists no flights"),
            (
                "m.csv",
                "structure,flight,date\nbridge,a.mcap,2026-01-01\nfleet,b.mcap,2026-01-01\n",
                "row 2: structure 'fleet' is reserved",
            ),
            (
                "m.toml",
                "[[flight]]\nstructure = \"slurm\"\ndate = 2026-01-01\nflight = \"a.mcap\"\n",
                "flight 1: structure 'slurm' is reserved",
            ),
            (
                "m.toml",
                "[[flight]]\nstructure = \"b\"\ndate = 2026-01-01\n",
                "flight 1: no `flight`",
            ),
            ("m.toml", "[[flights]]\n", "not a valid manifest"),
            (
                "m.toml",
                "[defaults]\nstructure = \"b\"\n",
                "[defaults] gives a flight's own column",
            ),
        ];
        for (name, text, expected) in cases {
            let e = load(name, text).unwrap_err().to_string();
            assert!(e.contains(expected), "{text:?}: {e}");
            assert!(!e.contains('\n'), "one line: {e}");
        }
    }

    #[test]
    fn a_flight_in_shards_is_a_task_per_share_numbered_after_the_flights_before_it() {
        let m = load(
            "m.csv",
            "structure,flight,date,shards\nb,a.mcap,2026-01-01,\nb,c.mcap,2026-01-02,3\nc,d.mcap,2026-01-01,1\n",
        )
        .unwrap();
        let tasks: Vec<(usize, Option<String>)> = m
            .tasks()
            .iter()
            .map(|t| (t.flight, t.share.map(|s| s.to_string())))
            .collect();
        let share = |s: &str| Some(s.to_string());
        assert_eq!(
            tasks,
            [
                (0, None),
                (1, share("1/3")),
                (1, share("2/3")),
                (1, share("3/3")),
                (2, None)
            ]
        );
        assert_eq!(m.task(4).unwrap().index, 4);
        let e = m.task(5).unwrap_err().to_string();
        assert!(e.contains("has 5 tasks"), "{e}");
        assert!(e.contains("indexed 0 to 4; there is no task 5"), "{e}");
        let e = load(
            "m.csv",
            "structure,flight,date,shards\nb,a.mcap,2026-01-01,0\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("row 1: shards 0 is not a number of shares"),
            "{e}"
        );
    }
}
