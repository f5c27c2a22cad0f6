//! End-to-end tests of `postflight record`: simulated flights with cracks
//! of known widths on known elements (single and in patterns), through
//! `postflight run`; the record's quantities against the same rule applied
//! to the simulator's truth, and its submission files read back by Python's
//! own XML and JSON Schema readers.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use postflight_core::condition::CrackLimits;
use postflight_core::outputs::record::ElementRecord;
use postflight_core::outputs::record::{PendingRule, Unit};
use postflight_core::table::Row;
use postflight_core::{RunDir, Stage};
use record::Decisions;
use record::RecordConfig;
use record::cracks::CountedCrack;
use record::cracks::counted_cracks;
use record::quantities::tally;
use record::stage::lay_out;

use crate::common::*;

/// The owner's numbers every test flight's record is made with; what the
/// flights did not see counts as state 1, so that states 2 to 4 are what
/// the flight saw.
const OWNER: &str = "[record]\nstructure_number = \"000000000012345\"\nstate_code = \"06\"\nnot_inspected = \"cs1\"\n";

/// Cracks alone, 0.5 to 4 mm wide at their widest (states 2 and 3), and in
/// patterns of fine cracks (0.4 to 1 mm: state 2 by width, 3 where the
/// pattern is heavy), seen finely enough to measure (a long lens: about
/// 1.2 mm a pixel at the plan's standoff).
const CRACKS: [&str; 10] = [
    "--cracks",
    "150",
    "--crack-patterns",
    "30",
    "--crack-widths",
    "2,5",
    "--pattern-widths",
    "0.6,1.0",
    "--focal",
    "2000",
];

/// A flight simulated with `sim_args`, run whole with `config` into a run
/// of its own, once per test process: (sim dir, run dir).
fn flown(name: &str, sim_args: &[&str], config: &str) -> (PathBuf, PathBuf) {
    let sim = simulated(sim_args);
    let dir = locked_fixture_dir(&format!("record-{name}"));
    let config_file = dir.join("postflight.toml");
    std::fs::write(&config_file, config).unwrap();
    let run = dir.join("run");
    let out = postflight(
        &[
            "run",
            "--flight",
            sim.join("flight.mcap").to_str().unwrap(),
            "--plan",
            sim.join("plan.json").to_str().unwrap(),
            "--config",
            config_file.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ],
        &dir,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    (sim, run)
}

/// The girder bridge with cracks alone and in patterns.
fn girder_bridge() -> &'static (PathBuf, PathBuf) {
    static FLOWN: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    FLOWN.get_or_init(|| flown("girder-bridge", &CRACKS, OWNER))
}

/// The footbridge: a slab on two columns, its beam recorded as a slab (38).
fn footbridge() -> &'static (PathBuf, PathBuf) {
    static FLOWN: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    FLOWN.get_or_init(|| {
        let mesh = root().join("tests/fixtures/footbridge.obj");
        let mut args = vec!["--mesh", mesh.to_str().unwrap()];
        // Fewer on its 40 m² than on the girder bridge's 600.
        args.extend(["--cracks", "30", "--crack-patterns", "6"]);
        args.extend(&CRACKS[4..]);
        let config = format!("{OWNER}[[record.element]]\nname = \"deck\"\nnumber = 38\n");
        flown("footbridge", &args, &config)
    })
}

/// The truth's cracks some frame saw, as the record counts a crack: its
/// lines, on the element coverage names where it is, in the state its
/// widest point puts it in.
fn truth_cracks(sim: &Path, run: &RunDir) -> Vec<CountedCrack> {
    let truth = read_json(&sim.join("truth.json"));
    let seen: std::collections::BTreeSet<i64> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|f| f["cracks"].as_array().unwrap().iter())
        .map(|c| c["id"].as_i64().unwrap())
        .collect();
    let layout = lay_out(run, &RecordConfig::default()).unwrap();
    let limits = CrackLimits::default();
    truth["cracks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| seen.contains(&c["id"].as_i64().unwrap()))
        .filter_map(|c| {
            let lines: Vec<Vec<[f64; 3]>> = c["lines"]
                .as_array()
                .unwrap()
                .iter()
                .map(|l| l.as_array().unwrap().iter().map(vec3).collect())
                .collect();
            let points: Vec<&[f64; 3]> = lines.iter().flatten().collect();
            let n = points.len() as f64;
            let centroid = nalgebra::Point3::new(
                points.iter().map(|p| p[0]).sum::<f64>() / n,
                points.iter().map(|p| p[1]).sum::<f64>() / n,
                points.iter().map(|p| p[2]).sum::<f64>() / n,
            );
            let element = layout.element_map.element_at(&centroid)?;
            Some(CountedCrack {
                id: format!("truth {}", c["id"]),
                element: layout.element_map.structure.elements[element].name.clone(),
                lines,
                state: limits.state(f(&c["width_mm"])),
                sealed: false,
                pending: false,
            })
        })
        .collect()
}

/// The record's rows of `run`.
fn rows(run: &Path) -> Vec<ElementRecord> {
    let frame = read_parquet(&run.join("elements.parquet"));
    ElementRecord::rows(&frame).unwrap()
}

/// Whether candidate `c`'s trace runs along truth crack `t`: a tenth of its
/// points (and at least three) within 5 cm of `t`'s lines.
fn runs_along(c: &CountedCrack, t: &CountedCrack) -> bool {
    let lines = t.lines.iter().map(|l| {
        l.iter()
            .map(|p| nalgebra::Point3::from(*p))
            .collect::<Vec<_>>()
    });
    let lines: Vec<Vec<nalgebra::Point3<f64>>> = lines.collect();
    let points: Vec<nalgebra::Point3<f64>> = c
        .lines
        .iter()
        .flatten()
        .map(|p| nalgebra::Point3::from(*p))
        .collect();
    let near = points
        .iter()
        .filter(|p| {
            postflight_core::trace::distance_to_lines(p, lines.iter().map(|l| l.iter().copied()))
                < 0.05
        })
        .count();
    near >= 3 && 10 * near >= points.len()
}

/// The truth's cracks the flight found, by the record's rule, against the
/// record's rows: each element's and its defect's quantities in states 2
/// to 4 within 10% or one cell of each other. (What the detector misses is
/// its recall, scored in tests/localise.rs; this scores what the record
/// makes of the cracks found: their traces, widths, patterns and cells.)
/// Returns the quantity in states 2 and 3 over all elements.
fn agrees_with_truth(sim: &Path, run: &Path) -> [f64; 2] {
    let dir = RunDir::open(run, Stage::Record).unwrap();
    let layout = lay_out(&dir, &RecordConfig::default()).unwrap();
    let defects = postflight_core::outputs::localise::read_defects(&dir).unwrap();
    let cracking = |name: &str| {
        layout
            .elements
            .iter()
            .find(|e| e.name == name)
            .map(|e| e.aashto.cracking)
    };
    let (found, _) = counted_cracks(
        &defects,
        &Decisions::new(),
        PendingRule::Count,
        &Default::default(),
        &cracking,
    );
    let truth: Vec<CountedCrack> = truth_cracks(sim, &dir)
        .into_iter()
        .filter(|t| found.iter().any(|c| runs_along(c, t)))
        .collect();
    let recorded = rows(run);
    let mut seen = [0.0; 2];
    for element in &layout.elements {
        let on: Vec<&CountedCrack> = truth.iter().filter(|c| c.element == element.name).collect();
        let t = tally(element, &on);
        let one_cell = match element.aashto.unit {
            Unit::SquareMetres => element.cells.cell_m.powi(2),
            Unit::Metres => element.cells.cell_m,
            Unit::Each => 1.0,
        } * element.scale();
        let row = |defect: bool| {
            recorded
                .iter()
                .find(|r| r.element == element.name && r.parent.is_some() == defect)
        };
        let own = row(false).unwrap();
        let pairs = [
            (Some(own), Some(&t.element)),
            (row(true), t.defect.as_ref()),
        ];
        for (r, truth) in pairs {
            let measured = r.map_or([0.0; 3], |r| [r.cs2, r.cs3, r.cs4]);
            let truth = truth.map_or([0.0; 3], |t| [t.states[1], t.states[2], t.states[3]]);
            for (state, (m, t)) in measured.iter().zip(truth).enumerate() {
                assert!(
                    (m - t).abs() <= (0.1 * t).max(one_cell) + 1e-9,
                    "{}: state {} {m:.2} where the truth's cracks give {t:.2} (defect row: {})",
                    element.name,
                    state + 2,
                    r.is_some_and(|r| r.parent.is_some())
                );
            }
        }
        seen[0] += t.element.states[1];
        seen[1] += t.element.states[2];
    }
    seen
}

/// Every row's states sum to its total, and an element's inspected and
/// not inspected parts to its total.
fn rows_add_up(run: &Path) {
    for r in rows(run) {
        let sum = r.cs1 + r.cs2 + r.cs3 + r.cs4;
        assert!((sum - r.total).abs() < 1e-6 * r.total.max(1.0), "{r:?}");
        if r.parent.is_none() {
            let parts = r.inspected + r.not_inspected;
            assert!((parts - r.total).abs() < 1e-6 * r.total.max(1.0), "{r:?}");
        }
    }
}

#[test]
fn quantities_agree_with_the_rule_applied_to_the_truth() {
    let mut states = [0.0; 2];
    for (sim, run) in [girder_bridge(), footbridge()] {
        rows_add_up(run);
        let [fair, poor] = agrees_with_truth(sim, run);
        states = [states[0] + fair, states[1] + poor];
    }
    // Both states were there to agree on: moderate patterns in state 2,
    // wide cracks and heavy patterns in 3.
    assert!(states[0] > 0.5 && states[1] > 0.5, "{states:?}");
}

#[test]
fn the_submission_files_read_back_with_independent_readers() {
    let (_, run) = girder_bridge();
    let checked: serde_json::Value =
        serde_json::from_str(&python_fixture("check_record.py", &[run.to_str().unwrap()])).unwrap();
    let rows = rows(run);
    let defects = rows.iter().filter(|r| r.parent.is_some()).count();
    // One record per element and per defect, EPN and BE02 on the defects'.
    assert_eq!(checked["rows"], rows.len());
    assert_eq!(checked["xml"]["records"], rows.len());
    assert_eq!(checked["xml"]["defects"], defects);
    assert_eq!(checked["xml"]["state"], "06");
    assert_eq!(checked["snbi"]["items"], rows.len());
    assert_eq!(checked["snbi"]["with_be02"], defects);
    assert!(defects >= 3, "{rows:?}");
}

/// A copy of the girder bridge's run, for a test that changes it.
fn girder_bridge_copy(name: &str) -> PathBuf {
    let dir = locked_fixture_dir(&format!("record-{name}"));
    let run = dir.join("run");
    copy_dir(&girder_bridge().1, &run);
    run
}

fn record_ok(run: &Path, args: &[&str]) -> String {
    let mut all = vec!["record", "--run", run.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = postflight(&all, run.parent().unwrap());
    assert!(out.status.success(), "{}", stderr(&out));
    stdout(&out)
}

#[test]
fn a_rejected_crack_leaves_the_record_when_it_is_rebuilt() {
    let run = girder_bridge_copy("rejected");
    let dir = RunDir::open(&run, Stage::Record).unwrap();
    let layout = lay_out(&dir, &RecordConfig::default()).unwrap();
    let defects = postflight_core::outputs::localise::read_defects(&dir).unwrap();
    let cracking = |name: &str| {
        layout
            .elements
            .iter()
            .find(|e| e.name == name)
            .map(|e| e.aashto.cracking)
    };
    let (cracks, _) = counted_cracks(
        &defects,
        &Decisions::new(),
        PendingRule::Count,
        &Default::default(),
        &cracking,
    );
    // The element with the most in state 3, and its widest crack.
    let before = rows(&run);
    let element = before
        .iter()
        .filter(|r| r.parent.is_none())
        .max_by(|a, b| a.cs3.total_cmp(&b.cs3))
        .unwrap();
    let width = |id: &str| {
        let d = defects.iter().find(|d| d.id == id).unwrap();
        d.width.and_then(|w| w.max_mm).unwrap_or(0.0)
    };
    let on: Vec<&CountedCrack> = cracks
        .iter()
        .filter(|c| c.element == element.element)
        .collect();
    let widest = on
        .iter()
        .max_by(|a, b| width(&a.id).total_cmp(&width(&b.id)))
        .unwrap();
    // Its share: what the element's state 3 holds with it and without it.
    let laid = layout
        .elements
        .iter()
        .find(|e| e.name == element.element)
        .unwrap();
    let without: Vec<&CountedCrack> = on.iter().copied().filter(|c| c.id != widest.id).collect();
    let share = tally(laid, &on).element.states[2] - tally(laid, &without).element.states[2];
    assert!(
        share > 0.0,
        "{} adds nothing to {}",
        widest.id,
        element.element
    );

    let db = run.join("review.sqlite");
    let server = crate::review::Server::start(&run, &db, &[]);
    let (status, body) = crate::review::post_json(
        &crate::review::agent(),
        &crate::review::decisions_url(&server.base, &widest.id),
        &serde_json::json!({"version": 0, "verdict": "rejected", "reviewer": "kim"}),
    );
    assert_eq!(status, 201, "{body}");
    drop(server);
    record_ok(&run, &[]);
    let after = rows(&run);
    let now = after
        .iter()
        .find(|r| r.element == element.element && r.parent.is_none())
        .unwrap();
    assert!(
        (element.cs3 - now.cs3 - share).abs() < 1e-9,
        "{}: state 3 {} -> {}, where {} held {share}",
        element.element,
        element.cs3,
        now.cs3,
        widest.id
    );
    assert!(!now.candidates.split(',').any(|id| id == widest.id));
    let summary = read_json(&run.join("record.json"));
    assert_eq!(summary["candidates"]["rejected"], 1);
}
