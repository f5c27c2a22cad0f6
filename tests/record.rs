//! End-to-end tests of `postflight record`: simulated flights with cracks
//! of known widths on known elements (single and in patterns), through
//! `postflight run`; the record's quantities against the same rule applied
//! to the simulator's truth, and its submission files read back by Python's
//! own XML and JSON Schema readers.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use postflight_core::condition::{ConditionState, CrackLimits};
use postflight_core::outputs::record::ElementRecord;
use postflight_core::outputs::record::{NotInspectedRule, PendingRule, QuantitySource, Unit};
use postflight_core::table::Row;
use postflight_core::{RunDir, Stage};
use record::Decisions;
use record::RecordConfig;
use record::cracks::CountedCrack;
use record::quantities::tally;
use record::stage::{Layout, lay_out};

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
    run_simulated_with(&sim, &run, &["--config", config_file.to_str().unwrap()]);
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
            let lines = truth_lines(c);
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

/// The run's candidates the record counts before any decision.
fn found_cracks(dir: &RunDir, layout: &Layout) -> Vec<CountedCrack> {
    let defects = postflight_core::outputs::localise::read_defects(dir).unwrap();
    let pending = PendingRule::Count;
    layout
        .counted_cracks(&defects, &Decisions::new(), pending, &Default::default())
        .0
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
    let found = found_cracks(&dir, &layout);
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
            // The figures docs/evaluation.md quotes (`--nocapture`).
            eprintln!(
                "{} {}: states 2-4 {measured:.2?}, the truth's {truth:.2?}, one cell {one_cell:.2}",
                element.name,
                r.map_or(0, |r| r.number)
            );
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

/// The states 1 to 4 a record page shows for `element`'s own row, as
/// written.
fn shown_states(page: &str, element: &str) -> Vec<String> {
    let row = &page[page.find(&format!("<td>{element}</td>")).unwrap()..];
    let row = &row[..row.find("</tr>").unwrap()];
    // The numeric cells: the total, states 1 to 4, pending.
    let cells: Vec<String> = row
        .split("<td class=\"n\">")
        .skip(1)
        .map(|c| c[..c.find("</td>").unwrap()].to_string())
        .collect();
    cells[1..5].to_vec()
}

#[test]
fn a_rejected_crack_leaves_the_record_when_it_is_rebuilt() {
    let run = girder_bridge_copy("rejected");
    let dir = RunDir::open(&run, Stage::Record).unwrap();
    let layout = lay_out(&dir, &RecordConfig::default()).unwrap();
    let defects = postflight_core::outputs::localise::read_defects(&dir).unwrap();
    let cracks = found_cracks(&dir, &layout);
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
    // The review queue's view of the record follows the decision at once.
    let (status, page) =
        crate::review::get(&crate::review::agent(), &format!("{}/record", server.base));
    assert_eq!(status, 200, "{page}");
    let shown = shown_states(&page, &element.element);
    let expected = element.cs3 - share;
    assert_eq!(shown[2], format!("{expected:.1}"), "{shown:?}");
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

/// The footbridge flown round with a gimbal (most of its slab seen), and
/// the same flight with every frame east of 1.5 m short of the middle of
/// the span left
/// without a pose (as if it had never flown there), each localised,
/// covered and recorded with `OWNER`: (full run, half run).
fn half_a_slab() -> &'static (PathBuf, PathBuf) {
    static FLOWN: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    FLOWN.get_or_init(|| {
        let mesh = root().join("tests/fixtures/footbridge.obj");
        let args = ["--mesh", mesh.to_str().unwrap(), "--gimbal", "--cracks", "30"];
        let config = format!("{OWNER}[[record.element]]\nname = \"deck\"\nnumber = 38\n");
        let (sim, full) = flown("slab-full", &args, &config);
        let dir = locked_fixture_dir("record-slab-half");
        let half = dir.join("run");
        copy_dir(&full, &half);
        python_run(
            "import sys, pyarrow as pa, pyarrow.parquet as pq\n\
             t = pq.read_table(sys.argv[1])\n\
             east = [x is not None and x > -1.5 for x in t.column('x').to_pylist()]\n\
             for name in ['x', 'y', 'z', 'qx', 'qy', 'qz', 'qw']:\n\
             \x20   i = t.schema.get_field_index(name)\n\
             \x20   col = t.column(name).to_pylist()\n\
             \x20   t = t.set_column(i, name, pa.array([None if e else v for e, v in zip(east, col)], pa.float64()))\n\
             i = t.schema.get_field_index('pose_status')\n\
             status = t.column('pose_status').to_pylist()\n\
             t = t.set_column(i, 'pose_status', pa.array(['pose_gap' if e else s for e, s in zip(east, status)]))\n\
             pq.write_table(t, sys.argv[1])",
            &[half.join("frames.parquet")],
        );
        let (r, plan) = (half.to_str().unwrap(), sim.join("plan.json"));
        let config_file = dir.join("postflight.toml");
        std::fs::write(&config_file, &config).unwrap();
        let c = config_file.to_str().unwrap();
        for stage in ["localise", "coverage", "record"] {
            let mut all = vec![stage, "--run", r, "--config", c];
            if stage != "record" {
                all.extend(["--plan", plan.to_str().unwrap()]);
            }
            let out = postflight(&all, &dir);
            assert!(out.status.success(), "{stage}: {}", stderr(&out));
        }
        (full, half)
    })
}

/// The element row of `element`.
fn element_row(run: &Path, element: &str) -> ElementRecord {
    rows(run)
        .into_iter()
        .find(|r| r.element == element && r.parent.is_none())
        .unwrap()
}

/// The inspected quantity of `element` east of `x` metres.
fn inspected_east_of(run: &Path, element: &str, x: f64) -> f64 {
    let dir = RunDir::open(run, Stage::Record).unwrap();
    let layout = lay_out(&dir, &RecordConfig::default()).unwrap();
    let e = layout.elements.iter().find(|e| e.name == element).unwrap();
    e.cells
        .cells
        .iter()
        .filter(|((along, _), c)| c.inspected && *along as f64 * e.cells.cell_m >= x)
        .map(|(_, c)| c.quantity)
        .sum()
}

#[test]
fn a_flight_that_misses_half_the_slab_says_so() {
    let (full, half) = half_a_slab();
    let (whole, part) = (element_row(full, "deck"), element_row(half, "deck"));
    // The full flight saw most of the 12 x 1.5 m slab; without its east
    // half, about half of that, none of it east of the middle.
    assert!(whole.inspected > 0.6 * whole.total, "{whole:?}");
    let share = part.inspected / whole.inspected;
    assert!(
        (0.35..=0.65).contains(&share),
        "{} of {}",
        part.inspected,
        whole.inspected
    );
    assert!(inspected_east_of(full, "deck", 1.0) > 0.2 * whole.total);
    assert!(inspected_east_of(half, "deck", 1.0) < 0.05 * whole.total);
    assert!((part.total - whole.total).abs() < 1e-9);
    let summary = read_json(&half.join("record.json"));
    let deck = summary["elements"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["element"] == "deck")
        .unwrap();
    assert!((f(&deck["inspected_pct"]) - 100.0 * part.inspected / part.total).abs() < 1e-9);
}

#[test]
fn each_not_inspected_rule_does_as_documented() {
    let (full, half) = half_a_slab();
    let dir = locked_fixture_dir("record-rules");
    let run = dir.join("run");
    copy_dir(half, &run);
    let r = run.to_str().unwrap();
    let config = dir.join("postflight.toml");
    std::fs::write(
        &config,
        format!("{OWNER}[[record.element]]\nname = \"deck\"\nnumber = 38\n"),
    )
    .unwrap();
    let record_ok = |args: &[&str]| {
        let mut all = vec!["--config", config.to_str().unwrap()];
        all.extend_from_slice(args);
        record_ok(&run, &all)
    };
    // As the fixture made it: what was not seen is state 1, flagged.
    let cs1 = element_row(&run, "deck");
    assert!(
        rows(&run)
            .iter()
            .all(|r| r.not_inspected_rule == NotInspectedRule::Cs1)
    );
    let unseen = cs1.not_inspected;
    assert!(unseen > 0.3 * cs1.total, "{cs1:?}");
    let seen = [cs1.cs1 - unseen, cs1.cs2, cs1.cs3, cs1.cs4];
    let states = |r: &ElementRecord| [r.cs1, r.cs2, r.cs3, r.cs4];
    let close = |a: [f64; 4], b: [f64; 4]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-6);

    // Refused: the slab is under 80% inspected; its unseen part goes as
    // the part seen shows.
    let said = record_ok(&["--not-inspected", "refuse"]);
    assert!(
        said.contains("no submission files") && said.contains("deck"),
        "{said}"
    );
    assert!(!run.join("nbe.xml").exists() && !run.join("snbi-elements.json").exists());
    let summary = read_json(&run.join("record.json"));
    assert_eq!(summary["submission"]["state"], "refused");
    assert!(
        summary["submission"]["why"]
            .as_str()
            .unwrap()
            .contains("deck")
    );
    let refused = element_row(&run, "deck");
    let scale = refused.total / refused.inspected;
    assert!(
        close(states(&refused), seen.map(|q| q * scale)),
        "{refused:?}"
    );
    // Under a lower minimum the slab passes; the east column, never seen,
    // still does not (nothing seen shows what the rest is).
    let said = record_ok(&["--not-inspected", "refuse", "--min-inspected", "0"]);
    let why = read_json(&run.join("record.json"))["submission"]["why"].to_string();
    assert!(
        why.contains("nothing inspected of pier 2") && !why.contains("deck"),
        "{said}"
    );

    // From an earlier record: the slab's unseen part in the full flight's shares.
    let c = config.to_str().unwrap();
    let out = postflight(
        &[
            "record",
            "--run",
            r,
            "--config",
            c,
            "--not-inspected",
            "previous",
        ],
        &dir,
    );
    assert_fails_in_one_line(&out, "--previous");
    assert!(
        !run.join("record.json").exists(),
        "a failed record leaves none"
    );
    let earlier = element_row(full, "deck");
    let f = full.to_str().unwrap();
    record_ok(&["--not-inspected", "previous", "--previous", f]);
    let carried = element_row(&run, "deck");
    let shares = states(&earlier).map(|q| q / earlier.total);
    let expected: Vec<f64> = seen
        .iter()
        .zip(shares)
        .map(|(s, p)| s + unseen * p)
        .collect();
    assert!(
        close(states(&carried), expected.try_into().unwrap()),
        "{carried:?} from {earlier:?}"
    );
    assert_eq!(carried.not_inspected_rule, NotInspectedRule::Previous);
    assert!(run.join("nbe.xml").is_file() && run.join("snbi-elements.json").is_file());
    let summary = read_json(&run.join("record.json"));
    assert_eq!(summary["previous"], f);
    // The owner's inventory quantity wins over the measured one, and one
    // this far from it is a warning.
    let said = record_ok(&[
        "--element",
        "{name = \"deck\", number = 38, quantity = 40.0}",
    ]);
    let inventory = element_row(&run, "deck");
    assert!((inventory.total - 40.0).abs() < 1e-9, "{inventory:?}");
    assert_eq!(inventory.quantity_source, QuantitySource::Inventory);
    let warnings = read_json(&run.join("record.json"))["warnings"].to_string();
    assert!(
        warnings.contains("inventory quantity 40.0 m2 differs"),
        "{warnings} {said}"
    );
    // Candidates no reviewer has decided wait for one with pending = "skip":
    // none of this run's is decided, so no crack counts.
    record_ok(&["--pending", "skip"]);
    assert!(
        rows(&run)
            .iter()
            .all(|r| r.cs2 + r.cs3 + r.cs4 == 0.0 && r.pending == 0)
    );
    let counts = &read_json(&run.join("record.json"))["candidates"];
    assert!(counts["pending"].as_u64().unwrap() > 0, "{counts}");
    // An earlier record of another structure has no such slab.
    let other = girder_bridge().1.to_str().unwrap();
    let out = postflight(
        &[
            "record",
            "--run",
            r,
            "--not-inspected",
            "previous",
            "--previous",
            other,
        ],
        &dir,
    );
    assert_fails_in_one_line(&out, "has no row for element");
}

/// The pattern rule against the simulator's own patterns: every pattern
/// of the girder bridge's flight, drawn heavy (0.10-0.25 m apart) or
/// moderate (0.35-0.8 m), is found so, from its cracks' lines alone, and
/// its spacing within 2 cm of the drawn one.
#[test]
fn patterns_are_judged_by_the_spacing_they_were_drawn_at() {
    let truth = read_json(&simulated(&CRACKS).join("truth.json"));
    let mut groups: std::collections::BTreeMap<u64, Vec<&serde_json::Value>> = Default::default();
    for c in truth["cracks"].as_array().unwrap() {
        if let Some(n) = c["pattern"]["number"].as_u64() {
            groups.entry(n).or_default().push(c);
        }
    }
    assert!(groups.len() >= 20, "{} patterns", groups.len());
    let (mut heavy, mut moderate) = (0, 0);
    for cracks in groups.values() {
        let drawn = f(&cracks[0]["pattern"]["spacing_m"]);
        let lines: Vec<record::pattern::Line> = cracks
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let line: Vec<[f64; 3]> =
                    c["lines"][0].as_array().unwrap().iter().map(vec3).collect();
                record::pattern::sample(i, &line, 0.05)
            })
            .collect();
        let judged = record::pattern::patterns(cracks.len(), &lines);
        let expected = if drawn < 0.3 {
            ConditionState::Poor
        } else {
            ConditionState::Fair
        };
        for j in &judged {
            assert_eq!(j.state, Some(expected), "drawn {drawn} m apart: {judged:?}");
            assert!(
                (j.spacing_m.unwrap() - drawn).abs() < 0.02,
                "{j:?} drawn {drawn}"
            );
        }
        match expected {
            ConditionState::Poor => heavy += 1,
            _ => moderate += 1,
        }
    }
    assert!(
        heavy > 0 && moderate > 0,
        "{heavy} heavy, {moderate} moderate"
    );
}
