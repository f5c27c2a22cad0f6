//! End-to-end tests of `postflight replan` on a simulated flight: the
//! follow-up plan, judged by `postflight coverage --viewpoints`, inspects
//! every gap voxel it claims, the gaps it cannot plan are listed with a
//! reason, and no segment of the flown path comes within the clearance of
//! an occupied voxel of the map (checked here from map.ply, point by point).

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::*;
use nalgebra::{Point3, Vector3};
use postflight_core::map::{PointCloud, VoxelGrid, VoxelIndex, VoxelMap};
use serde_json::Value;

type Voxel = [i64; 3];

fn replan(run: &Path, args: &[&str]) -> Output {
    let mut all = vec!["replan", "--run", run.to_str().unwrap()];
    all.extend_from_slice(args);
    postflight(&all, run.parent().unwrap())
}

fn coverage(run: &Path, args: &[&str]) {
    let mut all = vec!["coverage", "--run", run.to_str().unwrap()];
    all.extend_from_slice(args);
    let out = postflight(&all, run.parent().unwrap());
    assert!(out.status.success(), "coverage: {}", stderr(&out));
}

/// (inspected, uninspectable) of every target voxel of a coverage table.
fn coverage_rows(path: &Path) -> HashMap<Voxel, (bool, bool)> {
    let df = read_parquet(path);
    let int = |c: &str| df.column(c).unwrap().i32().unwrap().clone();
    let boolean = |c: &str| df.column(c).unwrap().bool().unwrap().clone();
    let (x, y, z) = (int("voxel_x"), int("voxel_y"), int("voxel_z"));
    let (inspected, uninspectable) = (boolean("inspected"), boolean("uninspectable"));
    (0..df.height())
        .map(|i| {
            let v = [x.get(i), y.get(i), z.get(i)].map(|c| i64::from(c.unwrap()));
            (
                v,
                (inspected.get(i).unwrap(), uninspectable.get(i).unwrap()),
            )
        })
        .collect()
}

fn voxel(v: &Value) -> Voxel {
    let a = v.as_array().unwrap();
    [0, 1, 2].map(|k| a[k].as_i64().unwrap())
}

fn point(v: &Value) -> Point3<f64> {
    Point3::from(vec3(v))
}

/// A sortie's flown path.
fn path_of(sortie: &Value) -> Vec<Point3<f64>> {
    sortie["path"]
        .as_array()
        .unwrap()
        .iter()
        .map(point)
        .collect()
}

/// Occupied voxels of the simulator's map, on the replan's grid.
fn occupied(sim: &Path, plan: &Value) -> VoxelMap {
    let cloud = PointCloud::load(&sim.join("map.ply")).unwrap();
    let grid = VoxelGrid::new(f(&plan["resolution"]), Point3::from(vec3(&plan["origin"])));
    VoxelMap::from_points(grid, &cloud.points, 1)
}

/// Smallest distance from any point of the segment (sampled every 2 cm) to
/// the box of an occupied voxel.
fn segment_clearance(map: &VoxelMap, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let res = map.grid.resolution;
    let steps = ((b - a).norm() / 0.02).ceil().max(1.0) as usize;
    let mut nearest = f64::INFINITY;
    for i in 0..=steps {
        let p = a + (b - a) * (i as f64 / steps as f64);
        let c = map.grid.voxel_of(&p);
        for dx in -4..=4 {
            for dy in -4..=4 {
                for dz in -4..=4 {
                    let v = VoxelIndex([c.0[0] + dx, c.0[1] + dy, c.0[2] + dz]);
                    if map.is_occupied(v) {
                        let d = ((p - map.grid.center(v)).abs() - Vector3::repeat(res / 2.0))
                            .sup(&Vector3::zeros());
                        nearest = nearest.min(d.norm());
                    }
                }
            }
        }
    }
    nearest
}

/// A ROS camera_info calibration YAML (as camera_calibration writes it)
/// for a pinhole camera.
fn calibration_yaml(path: &Path, name: &str, width: u32, height: u32, f: f64) {
    let (cx, cy) = (f64::from(width) / 2.0, f64::from(height) / 2.0);
    let text = format!(
        "image_width: {width}\nimage_height: {height}\ncamera_name: {name}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{f}, 0, {cx}, 0, {f}, {cy}, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  data: [{f}, 0, {cx}, 0, 0, {f}, {cy}, 0, 0, 0, 1, 0]\n"
    );
    std::fs::write(path, text).unwrap();
}

/// A team of two cameras: the flight's (640 x 480, 960 px focal length),
/// and a wide one (1280 x 960, 700 px: its 6 mm GSD is reached at 4.2 m,
/// not 5) on a drone taking off elsewhere and flying faster. Each drone's
/// waypoints, judged by coverage as shots of its own camera, inspect every
/// gap voxel the plan gives them; judged as the other camera's, the first
/// drone's do not.
fn two_cameras_each_plan_for_their_own(run: &Path, plan_file: &Path) {
    let wide = run.join("wide.yaml");
    calibration_yaml(&wide, "wide", 1280, 960, 700.0);
    let config = run.join("team.toml");
    std::fs::write(
        &config,
        format!(
            "[[replan.drone]]\nname = \"zoom\"\n[[replan.drone]]\nname = \"wide\"\nhome = [12.0, -12.0, 1.0]\nspeed_m_s = 3.0\ncamera_info_file = \"{}\"\n",
            wide.display()
        ),
    )
    .unwrap();
    let args = [
        &EVERY_GAP_ONE_BATTERY[..],
        &[
            "--solver-time-limit",
            "3",
            "--config",
            config.to_str().unwrap(),
        ],
    ];
    let out = replan(run, &args.concat());
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let team = read_json(&run.join("replan.json"));
    let drones = team["drones"].as_array().unwrap();
    assert_eq!(drones.len(), 2, "{}", team["drones"]);
    assert_eq!(
        (drones[0]["name"].as_str(), drones[1]["name"].as_str()),
        (Some("zoom"), Some("wide"))
    );
    assert_eq!(drones[1]["image_size"], serde_json::json!([1280, 960]));
    assert_eq!(f(&drones[1]["focal_px"]), 700.0);
    let home = point(&drones[1]["home"]);
    for sortie in team["sorties"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["drone"] == 1)
    {
        let path = sortie["path"].as_array().unwrap();
        let (start, end) = (point(&path[0]), point(path.last().unwrap()));
        // From its own home (lifted clear of the ground if need be).
        assert!(
            (start.xy() - home.xy()).norm() < 1e-9 && start == end,
            "{start} {home}"
        );
    }

    let judged = |drone: usize, camera: Option<&Path>| {
        let csv = run.join(format!("replan-drone-{}.csv", drone + 1));
        let mut args = vec![
            "--plan".to_string(),
            plan_file.to_str().unwrap().into(),
            "--viewpoints".into(),
            csv.to_str().unwrap().into(),
        ];
        if let Some(c) = camera {
            args.extend(["--viewpoint-camera".into(), c.to_str().unwrap().into()]);
        }
        coverage(run, &args.iter().map(String::as_str).collect::<Vec<_>>());
        let rows = coverage_rows(&run.join("coverage-viewpoints.parquet"));
        let own: BTreeSet<Voxel> = team["sorties"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["drone"] == drone)
            .flat_map(|s| s["waypoints"].as_array().unwrap().iter())
            .flat_map(|w| w["gap_voxels"].as_array().unwrap().iter().map(voxel))
            .collect();
        let missed = own.iter().filter(|v| !rows[*v].0).count();
        (own.len(), missed)
    };
    let zoom = judged(0, None);
    let wide_own = judged(1, Some(&wide));
    let zoom_as_wide = judged(0, Some(&wide));
    eprintln!(
        "two cameras: zoom {} gaps ({} missed), wide {} gaps ({} missed); zoom's waypoints with the wide camera miss {}",
        zoom.0, zoom.1, wide_own.0, wide_own.1, zoom_as_wide.1
    );
    assert!(zoom.0 > 0 && wide_own.0 > 0, "both drones fly");
    assert_eq!(
        (zoom.1, wide_own.1),
        (0, 0),
        "each camera's waypoints inspect its gaps"
    );
    assert!(zoom_as_wide.1 > 0, "the cameras' View models differ");
}

/// A rectangle of the map frame, `[x0, y0, x1, y1]`, between two heights.
struct Zone {
    corners: [f64; 4],
    bottom: f64,
    top: f64,
}

impl Zone {
    fn contains(&self, p: &Point3<f64>) -> bool {
        let [x0, y0, x1, y1] = self.corners;
        (x0..=x1).contains(&p.x)
            && (y0..=y1).contains(&p.y)
            && (self.bottom..=self.top).contains(&p.z)
    }

    fn outline(&self) -> [[f64; 2]; 4] {
        let [x0, y0, x1, y1] = self.corners;
        [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    }
}

/// Keep-out zones over the girder bridge's deck (x -15 to 15 m, y -3.5 to
/// 3.5 m, top at 6.5 m): over its west half a column, given as GeoJSON on
/// the Earth (written by PROJ), and over its east half the air above the
/// deck, given in the settings; and a ceiling 3 m above the take-off, below
/// parts of `open_plan` (planned without them). No
/// waypoint and no point of the flown path (every 2 cm) is in a zone or
/// above the ceiling; the column is every mission's geofence, as PROJ
/// places it; every gap is planned or listed with a reason.
fn keep_out_zones_hold(run: &Path, gaps: &BTreeSet<Voxel>, open_plan: &Value) {
    let west = Zone {
        corners: [-16.0, -4.5, 0.0, 4.5],
        bottom: f64::NEG_INFINITY,
        top: f64::INFINITY,
    };
    let east = Zone {
        corners: [0.0, -4.5, 16.0, 4.5],
        bottom: 6.5,
        top: f64::INFINITY,
    };
    let zones_file = run.join("zones.geojson");
    let mut args = vec!["zone".to_string(), zones_file.to_str().unwrap().into()];
    args.extend(ZURICH.map(String::from));
    args.push("west carriageway".into());
    args.extend(west.outline().map(|[x, y]| format!("{x},{y}")));
    python_fixture("check_geo.py", &args);
    let config = run.join("airspace.toml");
    std::fs::write(
        &config,
        "[[replan.keep_out]]\nname = \"east carriageway\"\noutline = [[0.0, -4.5], [16.0, -4.5], [16.0, 4.5], [0.0, 4.5]]\nbottom_m = 6.5\n",
    )
    .unwrap();
    let zurich = ZURICH.join(",");
    let out = replan(
        run,
        &[
            &EVERY_GAP_ONE_BATTERY[..],
            &[
                "--solver-time-limit",
                "3",
                "--geo-origin",
                &zurich,
                "--ceiling",
                "3",
            ],
            &["--keep-out", zones_file.to_str().unwrap()],
            &["--config", config.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let plan = read_json(&run.join("replan.json"));
    assert_eq!(
        plan["keep_out"].as_array().unwrap().len(),
        2,
        "{}",
        plan["keep_out"]
    );
    let ceiling = f(&plan["ceiling_z_m"]);
    let highest = |plan: &Value| {
        plan["sorties"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|s| s["path"].as_array().unwrap().iter().map(|p| f(&p[2])))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    assert!(
        highest(open_plan) > ceiling + 0.5,
        "the ceiling binds: the open plan reaches {:.1} m, the ceiling is at {ceiling:.1} m",
        highest(open_plan)
    );
    let warnings = plan["warnings"].to_string();
    assert!(
        warnings.contains("'east carriageway' has an altitude band"),
        "{warnings}"
    );

    let mut points = 0;
    for sortie in plan["sorties"].as_array().unwrap() {
        for w in sortie["waypoints"].as_array().unwrap() {
            let p = Point3::new(f(&w["x"]), f(&w["y"]), f(&w["z"]));
            assert!(
                !west.contains(&p) && !east.contains(&p) && p.z <= ceiling,
                "waypoint {p}"
            );
        }
        let path = path_of(sortie);
        for s in path.windows(2) {
            let steps = ((s[1] - s[0]).norm() / 0.02).ceil().max(1.0) as usize;
            for i in 0..=steps {
                let p = s[0] + (s[1] - s[0]) * (i as f64 / steps as f64);
                assert!(
                    !west.contains(&p) && !east.contains(&p) && p.z <= ceiling + 1e-9,
                    "path point {p}"
                );
                points += 1;
            }
        }
    }
    let geo = ground_station_files(run, ZURICH);
    let fence = geo["fence"].as_array().unwrap();
    assert_eq!(fence.len(), 1, "the column alone is fenced: {geo}");
    let corners: Vec<Point3<f64>> = fence[0]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| Point3::new(f(&c[0]), f(&c[1]), 0.0))
        .collect();
    for (got, [x, y]) in corners.iter().zip(west.outline()) {
        assert!(
            (got - Point3::new(x, y, 0.0)).norm() < 0.01,
            "fence corner {got}, zone corner ({x}, {y})"
        );
    }

    let planned: BTreeSet<Voxel> = plan["sorties"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|s| s["waypoints"].as_array().unwrap().iter())
        .flat_map(|w| w["gap_voxels"].as_array().unwrap().iter().map(voxel))
        .collect();
    let unplanned: BTreeSet<Voxel> = plan["uninspectable_gaps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| voxel(&u["voxel"]))
        .collect();
    assert_eq!(
        &planned.union(&unplanned).copied().collect::<BTreeSet<_>>(),
        gaps
    );
    eprintln!(
        "keep-out: {} of {} gaps planned, {} waypoints, {points} path points checked, ceiling z {ceiling:.1}",
        planned.len(),
        gaps.len(),
        plan["waypoints"]
    );
}

/// Every gap, planned or not, with a battery that never splits the flight.
const EVERY_GAP_ONE_BATTERY: [&str; 4] = ["--gaps", "all", "--battery-minutes", "600"];

/// Geo origins of the map frame: `LAT,LON,ALT,YAW_DEG`.
const ZURICH: [&str; 4] = ["47.397742", "8.545594", "488.0", "23.5"];
const SYDNEY: [&str; 4] = ["-33.8568", "151.2153", "20.0", "-120.0"];

/// The ground-station files checked by PROJ against `replan.json`
/// (tests/fixtures/check_geo.py): every position within 1 cm, every
/// heading exact; returns the checker's summary.
fn ground_station_files(run: &Path, origin: [&str; 4]) -> Value {
    let out = std::process::Command::new(python())
        .arg(root().join("tests/fixtures/check_geo.py"))
        .arg("run")
        .arg(run)
        .args(origin)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(f(&summary["max_error_m"]) < 0.01, "{summary}");
    assert!(f(&summary["max_heading_error_rad"]) < 1e-9, "{summary}");
    assert!(summary["waypoints"].as_u64().unwrap() > 0, "{summary}");
    summary
}

fn flight(dir: &Path) -> (PathBuf, PathBuf) {
    let sim = simulate_into(dir, "bridge", &["--scene", "girder-bridge", "--seed", "1"]);
    let run = dir.join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    coverage(&run, &["--plan", sim.join("plan.json").to_str().unwrap()]);
    (sim, run)
}

#[test]
fn the_replan_inspects_every_coverable_gap_and_keeps_clear_of_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let (sim, run) = flight(dir.path());
    let plan_file = sim.join("plan.json");

    let before = coverage_rows(&run.join("coverage.parquet"));
    let gaps: BTreeSet<Voxel> = before
        .iter()
        .filter(|(_, (inspected, uninspectable))| !inspected && !uninspectable)
        .map(|(v, _)| *v)
        .collect();
    assert!(
        gaps.len() > 50,
        "the simulated flight leaves gaps: {}",
        gaps.len()
    );

    // Every gap, planned or not, in one battery.
    let zurich = ZURICH.join(",");
    let args = [
        &EVERY_GAP_ONE_BATTERY[..],
        &["--solver-time-limit", "3", "--geo-origin", &zurich],
    ];
    let out = replan(&run, &args.concat());
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let plan = read_json(&run.join("replan.json"));
    let geo = ground_station_files(&run, ZURICH);
    assert_eq!(geo["plans"], 1);
    assert_eq!(plan["gap_voxels"].as_u64().unwrap() as usize, gaps.len());
    // One viewpoint serves every gap it inspects: no more waypoints than a
    // greedy set cover of the gaps by the candidates.
    let (waypoints, cover) = (
        plan["waypoints"].as_u64().unwrap(),
        plan["set_cover_viewpoints"].as_u64().unwrap(),
    );
    assert!(
        waypoints <= cover,
        "{waypoints} waypoints, set cover {cover}"
    );

    // Every gap is planned at exactly one waypoint, or listed with a reason.
    let mut planned: Vec<Voxel> = Vec::new();
    for sortie in plan["sorties"].as_array().unwrap() {
        for w in sortie["waypoints"].as_array().unwrap() {
            planned.extend(w["gap_voxels"].as_array().unwrap().iter().map(voxel));
        }
    }
    let planned_set: BTreeSet<Voxel> = planned.iter().copied().collect();
    assert_eq!(
        planned.len(),
        planned_set.len(),
        "a gap voxel at two waypoints"
    );
    let unplanned: BTreeSet<Voxel> = plan["uninspectable_gaps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| {
            let reason = u["reason"].as_str().unwrap();
            assert!(
                ["no_clear_viewpoint", "unreachable"].contains(&reason),
                "{reason}"
            );
            voxel(&u["voxel"])
        })
        .collect();
    assert!(planned_set.is_disjoint(&unplanned));
    let accounted: BTreeSet<Voxel> = planned_set.union(&unplanned).copied().collect();
    assert_eq!(accounted, gaps);
    // Most gaps of a girder bridge in open air can be planned.
    assert!(
        planned_set.len() * 100 >= gaps.len() * 95,
        "{} of {}",
        planned_set.len(),
        gaps.len()
    );

    // The plan, judged by the coverage stage alone, inspects them all:
    // read from replan.json, and from replan.csv as a ground station gets
    // it (its waypoint rows, with their gimbal pitch).
    for file in ["replan.json", "replan.csv"] {
        coverage(
            &run,
            &[
                "--plan",
                plan_file.to_str().unwrap(),
                "--viewpoints",
                run.join(file).to_str().unwrap(),
            ],
        );
        let after = coverage_rows(&run.join("coverage-viewpoints.parquet"));
        let missed: Vec<&Voxel> = planned_set.iter().filter(|v| !after[*v].0).collect();
        assert!(
            missed.is_empty(),
            "{file}: {} planned gap voxels not inspected: {:?}",
            missed.len(),
            &missed[..missed.len().min(5)]
        );
    }

    // The flown path: home to home, through every waypoint in order, and
    // never within the clearance of the map.
    let map = occupied(&sim, &plan);
    let clearance = f(&plan["clearance_m"]);
    let home = point(&plan["home"]);
    let mut nearest = f64::INFINITY;
    for sortie in plan["sorties"].as_array().unwrap() {
        let path = path_of(sortie);
        assert_eq!(path.first(), Some(&home));
        assert_eq!(path.last(), Some(&home));
        let mut at = 0;
        for w in sortie["waypoints"].as_array().unwrap() {
            let p = Point3::new(f(&w["x"]), f(&w["y"]), f(&w["z"]));
            at += path[at..]
                .iter()
                .position(|q| *q == p)
                .expect("waypoints on the path, in order");
        }
        for s in path.windows(2) {
            nearest = nearest.min(segment_clearance(&map, &s[0], &s[1]));
        }
        let length: f64 = path.windows(2).map(|s| (s[1] - s[0]).norm()).sum();
        assert_close(length, f(&sortie["length_m"]), 1e-6, "sortie length");
    }
    assert!(
        nearest >= clearance,
        "the path comes {nearest:.3} m from the map (clearance {clearance} m)"
    );
    eprintln!(
        "{} gaps: {} planned, {} uninspectable; {} waypoints, {:.0} m; closest approach {nearest:.2} m; solver {}",
        gaps.len(),
        planned_set.len(),
        unplanned.len(),
        plan["waypoints"],
        f(&plan["length_m"]),
        plan["solver"]
    );

    // GATSBI's path format, X,Y,Z,Yaw, then gimbal pitch, sortie and kind,
    // under comments giving the frame and units; home to home.
    let csv = std::fs::read_to_string(run.join("replan.csv")).unwrap();
    assert!(csv.contains("# frame: map") && csv.contains("GimbalPitch: degrees"));
    let mut lines = csv.lines().filter(|l| !l.starts_with('#'));
    assert_eq!(lines.next(), Some("X,Y,Z,Yaw,GimbalPitch,Sortie,Point"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r.len() == 7));
    let number = |r: &[&str], k: usize| -> f64 { r[k].parse().unwrap() };
    let kinds: Vec<&str> = rows.iter().map(|r| r[6]).collect();
    assert_eq!(
        kinds.iter().filter(|k| **k == "waypoint").count() as u64,
        plan["waypoints"].as_u64().unwrap()
    );
    assert_eq!((kinds[0], *kinds.last().unwrap()), ("home", "home"));
    assert!(
        (number(&rows[0], 0) - home.x).abs() < 1e-3 && (number(&rows[0], 2) - home.z).abs() < 1e-3
    );
    // Each waypoint row's gimbal pitch is its waypoint's, in degrees down-negative.
    let waypoints: Vec<&serde_json::Value> = plan["sorties"][0]["waypoints"]
        .as_array()
        .unwrap()
        .iter()
        .collect();
    let first = rows.iter().find(|r| r[6] == "waypoint").unwrap();
    assert!((number(first, 4) + f(&waypoints[0]["gimbal_pitch"]).to_degrees()).abs() < 0.06);

    team_shares_the_flight(&run, &plan_file, &planned_set, &plan);
    keep_out_zones_hold(&run, &gaps, &plan);
    two_cameras_each_plan_for_their_own(&run, &plan_file);

    // Battery: sorties no longer than the limit, each from home and back,
    // planning the same gaps.
    let limit = f(&plan["length_m"]) / 3.0;
    let (limit_arg, sydney) = (
        limit.to_string(),
        format!("--geo-origin={}", SYDNEY.join(",")),
    );
    let args = [
        &EVERY_GAP_ONE_BATTERY[..],
        &[
            "--solver-time-limit",
            "2",
            "--max-sortie-length",
            &limit_arg,
            &sydney,
        ],
    ];
    let out = replan(&run, &args.concat());
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let split = read_json(&run.join("replan.json"));
    let sorties = split["sorties"].as_array().unwrap();
    assert!(sorties.len() >= 3, "{} sorties", sorties.len());
    // A mission per sortie, and none left of the single-sortie plan.
    let geo = ground_station_files(&run, SYDNEY);
    assert_eq!(geo["plans"].as_u64(), Some(sorties.len() as u64));
    let mut again: BTreeSet<Voxel> = BTreeSet::new();
    for s in sorties {
        assert!(f(&s["length_m"]) <= limit + 1e-6);
        let path = s["path"].as_array().unwrap();
        assert_eq!(point(&path[0]), point(&split["home"]));
        assert_eq!(point(path.last().unwrap()), point(&split["home"]));
        for w in s["waypoints"].as_array().unwrap() {
            again.extend(w["gap_voxels"].as_array().unwrap().iter().map(voxel));
        }
    }
    assert_eq!(again, planned_set);

    // Battery: sorties within its time, flying and hovering, each from home.
    let minutes = f(&plan["time_s"]) / 60.0 / 3.0;
    let out = replan(
        &run,
        &[
            "--gaps",
            "all",
            "--solver-time-limit",
            "2",
            "--battery-minutes",
            &minutes.to_string(),
        ],
    );
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let split = read_json(&run.join("replan.json"));
    let sorties = split["sorties"].as_array().unwrap();
    assert!(sorties.len() >= 3, "{} sorties", sorties.len());
    for s in sorties {
        let hover = f(&split["hover_s"]) * s["waypoints"].as_array().unwrap().len() as f64;
        let time = f(&s["length_m"]) / f(&split["speed_m_s"]) + hover;
        assert_close(time, f(&s["time_s"]), 1e-6, "sortie time");
        assert!(time <= minutes * 60.0 + 1e-6, "{time} s over {minutes} min");
        let path = s["path"].as_array().unwrap();
        assert_eq!(point(&path[0]), point(&split["home"]));
        assert_eq!(point(path.last().unwrap()), point(&split["home"]));
    }
    // The default: the planned voxels the flight missed, fewer than every gap.
    let out = replan(&run, &["--solver-time-limit", "2"]);
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let missed = read_json(&run.join("replan.json"));
    let table = read_parquet(&run.join("coverage.parquet"));
    let column = |c: &str| table.column(c).unwrap().bool().unwrap().clone();
    let (planned, inspected, uninspectable) = (
        column("planned"),
        column("inspected"),
        column("uninspectable"),
    );
    let planned_missed = (0..table.height())
        .filter(|&i| {
            planned.get(i) == Some(true)
                && inspected.get(i) == Some(false)
                && uninspectable.get(i) == Some(false)
        })
        .count();
    assert_eq!(missed["gaps"], "missed");
    assert_eq!(missed["gap_voxels"].as_u64(), Some(planned_missed as u64));
    assert!(planned_missed < gaps.len());

    focus_is_judged_and_planned_under_its_view_model(&run, &plan_file, &before);

    // A home far off the map (a point given in the wrong frame) would make
    // the space to plan in vast: refused in one line, within seconds.
    let started = std::time::Instant::now();
    let out = replan(&run, &["--home", "1e12,0,0"]);
    assert_fails_in_one_line(&out, "the space to plan in, round the map and home, spans");
    assert!(started.elapsed().as_secs() < 30, "{:?}", started.elapsed());

    // A team drone's camera file that is missing, or is no calibration:
    // named as the drone's, in one line however long the file.
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "not a calibration ".repeat(500)).unwrap();
    for (file, says) in [
        (
            dir.path().join("missing.yaml"),
            "check the path given as zoom's camera_info_file in --drone",
        ),
        (notes, "not a ROS camera calibration file"),
    ] {
        let drone = format!(
            "{{name = \"zoom\", camera_info_file = \"{}\"}}",
            file.display()
        );
        let out = replan(&run, &["--drone", &drone]);
        assert_fails_in_one_line(&out, says);
        assert!(stderr(&out).len() < 600, "{}", stderr(&out));
    }
}

/// A focus region around the east pier (x 7.4 to 8.6 m, y -2.5 to 2.5 m,
/// 5 m high) with a stricter View model: a GSD of 3 mm (so within 2.88 m
/// of the 960 px lens, against 5 m) and two views. Coverage judges its
/// voxels under that model (fewer inspected than under the run's); the
/// follow-up plans each of its gaps from two waypoints; and coverage,
/// judging the follow-up's viewpoints under the same settings, finds every
/// planned gap inspected.
fn focus_is_judged_and_planned_under_its_view_model(
    run: &Path,
    plan_file: &Path,
    base: &HashMap<Voxel, (bool, bool)>,
) {
    let config = run.join("focus.toml");
    std::fs::write(
        &config,
        "[[coverage.focus]]\nregion = { name = \"east pier\", outline = [[7.2, -2.7], [8.8, -2.7], [8.8, 2.7], [7.2, 2.7]], top_m = 5.0 }\nview = { max_gsd_mm = 3.0, views_required = 2 }\n",
    )
    .unwrap();
    let (plan_arg, config_arg) = (plan_file.to_str().unwrap(), config.to_str().unwrap());
    coverage(run, &["--plan", plan_arg, "--config", config_arg]);
    let summary = read_json(&run.join("coverage.json"));
    let focus = &summary["focus"][0];
    assert_eq!(focus["region"]["name"], "east pier");
    assert_eq!(f(&focus["view"]["max_gsd_mm"]), 3.0);
    let in_pier = |v: &Voxel| {
        let c = v.map(|i| i as f64 * 0.5 + 0.25);
        (7.2..=8.8).contains(&c[0]) && (-2.7..=2.7).contains(&c[1]) && c[2] <= 5.0
    };
    let strict = coverage_rows(&run.join("coverage.parquet"));
    let pier: Vec<&Voxel> = strict.keys().filter(|v| in_pier(v)).collect();
    assert_eq!(focus["target_voxels"].as_u64(), Some(pier.len() as u64));
    let inspected =
        |rows: &HashMap<Voxel, (bool, bool)>| pier.iter().filter(|v| rows[**v].0).count();
    assert!(
        inspected(&strict) < inspected(base),
        "the stricter model inspects fewer: {} against {}",
        inspected(&strict),
        inspected(base)
    );
    let focus_gaps: BTreeSet<Voxel> = pier
        .iter()
        .filter(|v| !strict[**v].0 && !strict[**v].1)
        .map(|v| **v)
        .collect();
    assert!(!focus_gaps.is_empty());

    let out = replan(
        run,
        &[&EVERY_GAP_ONE_BATTERY[..], &["--solver-time-limit", "3"]].concat(),
    );
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let plan = read_json(&run.join("replan.json"));
    let mut at_waypoints: HashMap<Voxel, usize> = HashMap::new();
    for sortie in plan["sorties"].as_array().unwrap() {
        for w in sortie["waypoints"].as_array().unwrap() {
            for v in w["gap_voxels"].as_array().unwrap().iter().map(voxel) {
                *at_waypoints.entry(v).or_default() += 1;
            }
        }
    }
    let planned: Vec<&Voxel> = focus_gaps
        .iter()
        .filter(|v| at_waypoints.contains_key(*v))
        .collect();
    assert!(
        planned.len() * 2 >= focus_gaps.len(),
        "{} of {} focus gaps planned",
        planned.len(),
        focus_gaps.len()
    );
    for v in &planned {
        assert_eq!(at_waypoints[*v], 2, "focus gap {v:?} at two waypoints");
    }
    for u in plan["uninspectable_gaps"].as_array().unwrap() {
        assert!(!at_waypoints.contains_key(&voxel(&u["voxel"])));
    }

    coverage(
        run,
        &[
            "--plan",
            plan_arg,
            "--config",
            config_arg,
            "--viewpoints",
            run.join("replan.json").to_str().unwrap(),
        ],
    );
    let judged = coverage_rows(&run.join("coverage-viewpoints.parquet"));
    let missed: Vec<&&Voxel> = planned.iter().filter(|v| !judged[**v].0).collect();
    assert!(
        missed.is_empty(),
        "{} planned focus gaps not inspected: {missed:?}",
        missed.len()
    );
    eprintln!(
        "focus: {} pier voxels, {} inspected under the run's model, {} under the focus model; {} gaps, {} planned from two waypoints",
        pier.len(),
        inspected(base),
        inspected(&strict),
        focus_gaps.len(),
        planned.len()
    );
}

/// Three drones share the same follow-up: together they inspect every gap
/// the one drone would (judged by coverage on the union of their routes),
/// the mission takes at most 40% of the one drone's time, and each drone
/// gets its own path and missions.
fn team_shares_the_flight(
    run: &Path,
    plan_file: &Path,
    planned: &BTreeSet<Voxel>,
    one_drone: &Value,
) {
    let zurich = ZURICH.join(",");
    let args = [
        &EVERY_GAP_ONE_BATTERY[..],
        &[
            "--solver-time-limit",
            "3",
            "--geo-origin",
            &zurich,
            "--drones",
            "3",
        ],
    ];
    let out = replan(run, &args.concat());
    assert!(out.status.success(), "replan: {}", stderr(&out));
    let team = read_json(&run.join("replan.json"));
    let drones = team["drones"].as_array().unwrap();
    assert_eq!(drones.len(), 3, "{}", team["drones"]);
    let (mission, alone) = (f(&team["mission_time_s"]), f(&one_drone["time_s"]));
    // Take-offs staggered until no two drones come within the clearance.
    let closest = f(&team["closest_drones_m"]);
    assert!(
        closest >= f(&team["clearance_m"]),
        "drones {closest:.2} m apart"
    );
    eprintln!("3 drones: the mission takes {mission:.0} s, one drone {alone:.0} s");
    assert!(
        mission <= 0.4 * alone,
        "{mission:.0} s against {alone:.0} s"
    );
    for (d, drone) in drones.iter().enumerate() {
        let own: Vec<&Value> = team["sorties"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| s["drone"] == d)
            .collect();
        let time: f64 = own.iter().map(|s| f(&s["time_s"])).sum();
        assert_close(time, f(&drone["time_s"]), 1e-6, "a drone's time");
        assert!(f(&drone["takeoff_s"]) + time <= mission + 1e-6);
        // Its own path file: its waypoints, home to home.
        let csv = std::fs::read_to_string(run.join(format!("replan-drone-{}.csv", d + 1))).unwrap();
        let waypoints = csv.lines().filter(|l| l.ends_with(",waypoint")).count();
        assert_eq!(waypoints as u64, drone["waypoints"].as_u64().unwrap());
    }
    // The missions: one per drone and sortie, each checked against PROJ.
    let geo = ground_station_files(run, ZURICH);
    assert_eq!(
        geo["plans"].as_u64(),
        Some(team["sorties"].as_array().unwrap().len() as u64)
    );
    // Together, every gap the one drone plans.
    coverage(
        run,
        &[
            "--plan",
            plan_file.to_str().unwrap(),
            "--viewpoints",
            run.join("replan.json").to_str().unwrap(),
        ],
    );
    let after = coverage_rows(&run.join("coverage-viewpoints.parquet"));
    let missed = planned.iter().filter(|v| !after[*v].0).count();
    assert_eq!(
        missed, 0,
        "{missed} planned gap voxels not inspected by the team"
    );
}

#[test]
fn no_gaps_give_an_empty_plan_and_bad_runs_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_into(dir.path(), "bridge", &["--frames", "60"]);
    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);

    // Before coverage: the error names the stage to run.
    let out = replan(&run, &[]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("postflight coverage"),
        "{}",
        stderr(&out)
    );

    // Targets: only voxels the flight inspected, so nothing is left to plan.
    coverage(&run, &["--plan", sim.join("plan.json").to_str().unwrap()]);
    let rows = coverage_rows(&run.join("coverage.parquet"));
    let seen: Vec<Voxel> = rows
        .iter()
        .filter(|(_, r)| r.0)
        .map(|(v, _)| *v)
        .take(5)
        .collect();
    assert!(!seen.is_empty());
    let boxes: Vec<Value> = seen
        .iter()
        .map(|v| {
            let c = v.map(|i| i as f64 * 0.5 + 0.25);
            serde_json::json!({"min": [c[0] - 0.1, c[1] - 0.1, c[2] - 0.1], "max": [c[0] + 0.1, c[1] + 0.1, c[2] + 0.1]})
        })
        .collect();
    let boxes_file = dir.path().join("boxes.json");
    std::fs::write(&boxes_file, serde_json::to_string(&boxes).unwrap()).unwrap();
    coverage(&run, &["--target-boxes", boxes_file.to_str().unwrap()]);
    let out = replan(&run, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("no gaps"));
    let plan = read_json(&run.join("replan.json"));
    assert_eq!(plan["gap_voxels"], 0);
    assert_eq!(plan["waypoints"], 0);
    assert!(plan["sorties"].as_array().unwrap().is_empty());
    let csv = std::fs::read_to_string(run.join("replan.csv")).unwrap();
    assert!(
        csv.ends_with("\nX,Y,Z,Yaw,GimbalPitch,Sortie,Point\n"),
        "{csv}"
    );

    // Nonsense options are refused with the option named.
    let out = replan(&run, &["--max-sortie-length=-5"]);
    assert!(
        stderr(&out).contains("--max-sortie-length"),
        "{}",
        stderr(&out)
    );
    let out = replan(&run, &["--home", "1,2"]);
    assert!(stderr(&out).contains("X,Y,Z"), "{}", stderr(&out));
    let out = replan(&run, &["--drones", "3", "--drone", "{name = \"a\"}"]);
    assert!(
        stderr(&out).contains("--drones must be 1 or the number of --drone entries (1)"),
        "{}",
        stderr(&out)
    );
    let out = replan(&run, &["--drone", "{name = \"a\", speed_m_s = 0}"]);
    assert!(
        stderr(&out).contains("--drone must be positive (it is a's speed_m_s 0)"),
        "{}",
        stderr(&out)
    );
    let out = replan(&run, &["--ceiling", "0"]);
    assert!(
        stderr(&out).contains("--ceiling must be a positive number"),
        "{}",
        stderr(&out)
    );
    // Values no flight has, which would keep the planner busy for ever or
    // write non-finite numbers: refused in one line, naming the option.
    for (args, says) in [
        (["--clearance", "1e9"], "--clearance must be 0 to 10 metres"),
        (["--clearance", "inf"], "--clearance must be 0 to 10 metres"),
        (["--hover", "inf"], "--hover must be 0 or more seconds"),
        (["--speed", "inf"], "--speed must be a positive number"),
        (["--drones", "100000"], "--drones must be 1 to 50 drones"),
        (
            ["--drone", "{name = \"a\", home = [0, nan, 0]}"],
            "--drone must be a point [x, y, z] in the map frame, metres (it is a's home [0, NaN, 0])",
        ),
    ] {
        assert_fails_in_one_line(&replan(&run, &args), says);
    }
    let config = dir.path().join("nan-home.toml");
    std::fs::write(&config, "[replan]\nhome = [nan, 0, 0]\n").unwrap();
    assert_fails_in_one_line(
        &replan(&run, &["--config", config.to_str().unwrap()]),
        "must be a point [x, y, z] in the map frame, metres (it is [NaN, 0, 0])",
    );

    // Keep-out zones that cannot be used, each refused in one line that
    // says why, with replan.json gone rather than stale.
    let refused = |config: &str, args: &[&str], why: &str| {
        let file = dir.path().join("zones.toml");
        std::fs::write(&file, config).unwrap();
        let mut all = vec!["--config", file.to_str().unwrap(), "--home", "0,-20,3"];
        all.extend_from_slice(args);
        let out = replan(&run, &all);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert!(stderr(&out).contains(why), "{}", stderr(&out));
        assert_eq!(stderr(&out).trim().lines().count(), 1, "{}", stderr(&out));
        assert!(!run.join("replan.json").exists());
    };
    let zone =
        |outline: &str| format!("[[replan.keep_out]]\nname = \"pad\"\noutline = {outline}\n");
    refused(
        &zone("[[0, 0], [1, 1]]"),
        &[],
        "'pad' has 2 corners; an outline needs at least 3",
    );
    refused(
        &zone("[[-1, -21], [1, -21], [1, -19], [-1, -19]]"),
        &[],
        "the take-off point (0.0, -20.0, 3.0) is inside keep-out zone 'pad'",
    );
    let geojson = dir.path().join("zones.geojson");
    std::fs::write(&geojson, r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"name": "rail", "upperLimit": 30, "upperVerticalReference": "AMSL"}, "geometry": {"type": "Polygon", "coordinates": [[[8.5, 47.4], [8.6, 47.4], [8.6, 47.5], [8.5, 47.4]]]}}]}"#).unwrap();
    let zones = geojson.to_str().unwrap();
    refused(
        "",
        &["--keep-out", zones],
        "places keep-out zones on the Earth, but the map frame's place on it is unknown; give --geo-origin",
    );
    refused(
        "",
        &["--keep-out", zones, "--geo-origin", "47.3,8.4,400"],
        "rail: upperVerticalReference is AMSL, which needs a geoid model",
    );

    // Coverage too (last: a failed coverage removes its summary): a face needing more views than replan can plan.
    let out = postflight(
        &[
            "coverage",
            "--run",
            run.to_str().unwrap(),
            "--views",
            "4000000000",
        ],
        dir.path(),
    );
    assert_fails_in_one_line(&out, "--views must be 1 to 64 views");
}
