//! OctoMap maps written by Debian's octomap-tools (the OctoMap library's own
//! `log2graph` and `graph2tree`, an independent writer): the occupied voxels
//! postflight reads from `.bt` and `.ot` are those of the points the tree
//! was built from, pruned or not, and a flight's coverage over such a map is
//! its coverage over the PLY of the same points.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::common::*;
use nalgebra::Point3;
use postflight_core::map::octomap::{self, Format};
use postflight_core::map::{PointCloud, VoxelGrid};

fn voxels(points: &[Point3<f64>], grid: &VoxelGrid) -> BTreeSet<[i32; 3]> {
    points.iter().map(|p| grid.voxel_of(p).0).collect()
}

/// The simulated flight the coverage tests share, simulated once.
fn flight() -> &'static Path {
    static SIM: OnceLock<PathBuf> = OnceLock::new();
    SIM.get_or_init(|| {
        let dir = locked_fixture_dir("octomap-flight");
        simulate_into(&dir, "sim", &["--frames", "60"])
    })
}

/// The centres of the map's occupied voxels at `res`: what an OctoMap of
/// the map holds (a tree cannot say where in a voxel a point was).
fn map_voxel_centres(sim: &Path, res: f64) -> Vec<Point3<f64>> {
    let cloud = PointCloud::load(&sim.join("map.ply")).unwrap();
    let grid = VoxelGrid::new(res, Point3::origin());
    voxels(&cloud.points, &grid)
        .into_iter()
        .map(|v| grid.center(postflight_core::map::VoxelIndex(v)))
        .collect()
}

#[test]
fn octomap_trees_read_as_the_voxels_of_their_points_pruned_at_several_depths() {
    let dir = tempfile::tempdir().unwrap();
    let res = 0.1;
    // A solid cube of 8 voxels a side on an 8-voxel boundary (OctoMap
    // prunes it to one leaf three levels up), a one-voxel wall beside it
    // (unprunable), and points in negative coordinates.
    let mut points = Vec::new();
    for (i, j, k) in (0..8).flat_map(|i| (0..8).flat_map(move |j| (0..8).map(move |k| (i, j, k)))) {
        points.push(Point3::new(1.6, 2.4, 0.8) + nalgebra::Vector3::new(i, j, k).cast() * res);
    }
    for (j, k) in (0..30).flat_map(|j| (0..10).map(move |k| (j, k))) {
        points.push(Point3::new(
            -5.0,
            -1.5 + 0.1 * f64::from(j),
            -0.5 + 0.1 * f64::from(k),
        ));
    }
    let points: Vec<_> = points
        .iter()
        .map(|p| p + nalgebra::Vector3::repeat(res / 2.0))
        .collect();
    let grid = VoxelGrid::new(res, Point3::origin());
    let want = voxels(&points, &grid);
    for (tree, format) in octomap_of(dir.path(), "cube", &points, res)
        .iter()
        .zip([Format::Binary, Format::Full])
    {
        let map = octomap::parse(&std::fs::read(tree).unwrap(), format).unwrap();
        assert_eq!(map.resolution, res);
        assert_eq!(voxels(&map.points, &grid), want, "{}", tree.display());
        assert_eq!(map.points.len(), want.len());
        let depths: Vec<u32> = map.leaves_by_depth.keys().copied().collect();
        assert!(
            depths.contains(&16) && depths.iter().any(|&d| d <= 14),
            "leaves by depth: {:?}",
            map.leaves_by_depth
        );
        // The same through the map loader every stage uses.
        let cloud = PointCloud::load(tree).unwrap();
        assert_eq!(voxels(&cloud.points, &grid), want);
    }
}

#[test]
fn coverage_over_an_octomap_of_the_map_is_coverage_over_its_ply() {
    let dir = tempfile::tempdir().unwrap();
    let sim = flight();
    let plan = read_json(&sim.join("plan.json"));
    let res = f(&plan["resolution"]);
    // The tree holds the map's voxels; the PLY of their centres is the
    // reference.
    let centres = map_voxel_centres(sim, res);
    let centres_ply = dir.path().join("centres.ply");
    write_ply(&centres_ply, &centres);
    let [bt, ot] = octomap_of(dir.path(), "map", &centres, res);

    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    let coverage_with = |map: &Path| {
        let out = postflight(
            &[
                "coverage",
                "--run",
                run.to_str().unwrap(),
                "--plan",
                sim.join("plan.json").to_str().unwrap(),
                "--map",
                map.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        read_parquet(&run.join("coverage.parquet"))
    };
    let reference = coverage_with(&centres_ply);
    assert!(reference.height() > 100);
    for tree in [bt, ot] {
        assert!(
            coverage_with(&tree).equals_missing(&reference),
            "{}",
            tree.display()
        );
    }
    // The map matters: without every other voxel, coverage is not the same.
    let sparse: Vec<_> = centres.iter().step_by(2).copied().collect();
    let [sparse_bt, _] = octomap_of(dir.path(), "sparse", &sparse, res);
    assert!(!coverage_with(&sparse_bt).equals_missing(&reference));
}

#[test]
fn a_segmented_octomap_gives_the_targets_of_its_cloud_in_coverage_and_in_run() {
    let dir = tempfile::tempdir().unwrap();
    let sim = flight();
    let plan = read_json(&sim.join("plan.json"));
    let res = f(&plan["resolution"]);
    // The structure, segmented: the centres of the plan's target voxels.
    let centres: Vec<Point3<f64>> = plan["target_voxels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| Point3::from([0, 1, 2].map(|a| (v[a].as_f64().unwrap() + 0.5) * res)))
        .collect();
    let cloud = dir.path().join("structure.ply");
    write_ply(&cloud, &centres);
    let [segmented, _] = octomap_of(dir.path(), "structure", &centres, res);

    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    let coverage_with = |flag: &str, file: &Path| {
        let out = postflight(
            &[
                "coverage",
                "--run",
                run.to_str().unwrap(),
                flag,
                file.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        read_parquet(&run.join("coverage.parquet"))
    };
    let from_cloud = coverage_with("--target-cloud", &cloud);
    assert_eq!(from_cloud.height(), centres.len());
    assert!(coverage_with("--target-map", &segmented).equals_missing(&from_cloud));

    // `postflight run` takes the same targets and, without a plan, still
    // judges coverage and plans the follow-up flight.
    let config = dir.path().join("postflight.toml");
    std::fs::write(&config, "[replan]\nsolver_time_limit_s = 0.5\n").unwrap();
    let full = dir.path().join("full");
    let out = postflight(
        &[
            "run",
            "--flight",
            sim.join("flight.mcap").to_str().unwrap(),
            "--target-map",
            segmented.to_str().unwrap(),
            "--model",
            root()
                .join("detect/models/crack-baked.onnx")
                .to_str()
                .unwrap(),
            "--config",
            config.to_str().unwrap(),
            "--out",
            full.to_str().unwrap(),
            "-q",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(read_parquet(&full.join("coverage.parquet")).equals_missing(&from_cloud));
    assert!(full.join("replan.json").is_file());
    let log = read_json(&full.join("pipeline.json"));
    let coverage = log["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["stage"] == "coverage")
        .unwrap();
    assert!(
        coverage["inputs"]["targets"]["sha256"].is_string(),
        "{coverage}"
    );
}

/// GATSBI's inputs: its inspection path as `X,Y,Z,Yaw` rows and the
/// structure as boxes, over an OctoMap of the map.
#[test]
fn a_bt_map_an_xyz_yaw_path_and_target_boxes_give_the_coverage_of_ply_and_plan_json() {
    let dir = tempfile::tempdir().unwrap();
    let sim = flight();
    let plan_json = sim.join("plan.json");
    let plan = read_json(&plan_json);
    let res = f(&plan["resolution"]);
    let centres = map_voxel_centres(sim, res);
    let ply = dir.path().join("centres.ply");
    write_ply(&ply, &centres);
    let [bt, _] = octomap_of(dir.path(), "map", &centres, res);

    // One box around the plan's targets, and the plan's viewpoints as a
    // path: in radians with a header, and in degrees without one.
    let targets = plan["target_voxels"].as_array().unwrap();
    let corner = |pick: fn(f64, f64) -> f64, shift: f64| {
        [0, 1, 2].map(|a| {
            let i = targets
                .iter()
                .map(|v| v[a].as_f64().unwrap())
                .fold(targets[0][a].as_f64().unwrap(), pick);
            (i + shift) * res
        })
    };
    let boxes = dir.path().join("boxes.json");
    let boxes_json =
        serde_json::json!([{"min": corner(f64::min, 0.0), "max": corner(f64::max, 1.0)}]);
    std::fs::write(&boxes, boxes_json.to_string()).unwrap();
    let path_csv = |degrees: bool| {
        let mut text = if degrees {
            String::new()
        } else {
            "X,Y,Z,Yaw\n".into()
        };
        for v in plan["viewpoints"].as_array().unwrap() {
            let p = &v["position"];
            let yaw = f(&v["yaw"]);
            let yaw = if degrees { yaw.to_degrees() } else { yaw };
            text += &format!("{},{},{},{yaw}\n", f(&p[0]), f(&p[1]), f(&p[2]));
        }
        let file = dir.path().join(format!("path-{degrees}.csv"));
        std::fs::write(&file, text).unwrap();
        file
    };
    let (radians, degrees) = (path_csv(false), path_csv(true));

    let run = dir.path().join("run");
    ingest_ok(&sim.join("flight.mcap"), &run, &[]);
    let coverage_with = |args: &[&str]| {
        let (run_arg, boxes) = (run.to_str().unwrap(), boxes.to_str().unwrap());
        let mut all = vec!["coverage", "--run", run_arg, "--target-boxes", boxes];
        all.extend(args);
        let out = postflight(&all, dir.path());
        assert!(out.status.success(), "{}", stderr(&out));
        read_parquet(&run.join("coverage.parquet"))
    };
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    let reference = coverage_with(&["--plan", &s(&plan_json), "--map", &s(&ply)]);
    assert!(reference.height() > 100);
    let planned = reference.column("planned").unwrap().bool().unwrap();
    assert!(
        planned.sum().unwrap() > 100,
        "the path's viewpoints are judged"
    );
    let from_path = coverage_with(&["--plan", &s(&radians), "--map", &s(&bt)]);
    assert!(from_path.equals_missing(&reference));
    let in_degrees = coverage_with(&["--plan", &s(&degrees), "--yaw-degrees", "--map", &s(&bt)]);
    assert!(in_degrees.equals_missing(&reference));

    // A path names no targets: without a target option, coverage says so
    // and writes nothing, and `run` says so before it starts.
    let out = postflight(
        &[
            "coverage",
            "--run",
            &s(&run),
            "--plan",
            &s(&radians),
            "--map",
            &s(&bt),
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("waypoint path, which names no targets"),
        "{}",
        stderr(&out)
    );
    assert!(!run.join("coverage.json").exists());
    let out = postflight(
        &[
            "run",
            "--flight",
            &s(&sim.join("flight.mcap")),
            "--plan",
            &s(&radians),
            "--out",
            &s(&dir.path().join("never")),
        ],
        dir.path(),
    );
    assert!(stderr(&out).contains("--target-boxes"), "{}", stderr(&out));
    assert!(!dir.path().join("never").exists());
}
