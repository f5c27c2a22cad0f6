//! Photo folders as flights. The default simulated flight is written as a
//! DJI photo folder by other hands: exiftool tags each frame's JPEG with
//! its true camera pose put on the Earth by PROJ, with 2 cm of RTK-like
//! noise (EXIF GPS and times; XMP drone-dji gimbal angles, speed, lens and
//! RTK), and laspy writes the map as a LAZ in UTM. `postflight run` on the
//! folder poses every photo, places the candidates within 10 cm of the
//! truth cracks on the Earth (WGS 84, compared through PROJ) and finds the
//! coverage of the same flight's MCAP run. A photo without GPS, a file
//! that is not a JPEG and a LAZ without a CRS are each named in one line,
//! and nothing that looks complete is written.

use std::path::{Path, PathBuf};

use crate::common::*;
use nalgebra::Point3;
use serde_json::Value;

/// Where the simulator's world frame is put on the Earth (east-north-up,
/// altitude above the ellipsoid): Zurich.
const ORIGIN: &str = "47.3977,8.5456,488.0";
/// The UTM zone there.
const UTM_32N: &str = "32632";

/// The simulated flight `args` as a DJI photo folder in `dir`; its photos'
/// true positions as `dji_photos.py` lists them.
fn photo_folder(sim: &Path, dir: &Path, extra: &[&str]) -> (PathBuf, Value) {
    let photos = dir.join("photos");
    let mut args = vec![sim.to_str().unwrap(), photos.to_str().unwrap(), ORIGIN];
    args.extend(extra);
    let listed = python_fixture("dji_photos.py", &args);
    (photos, serde_json::from_str(&listed).unwrap())
}

/// The warnings a run's ingest.json lists.
fn ingest_warnings(run: &Path) -> Vec<String> {
    let summary = read_json(&run.join("ingest.json"));
    let warnings = summary["warnings"].as_array().unwrap().iter();
    warnings.map(|w| w.as_str().unwrap().to_string()).collect()
}

/// `postflight COMMAND --photos PHOTOS ARGS... --out OUT`.
fn on_photos(command: &str, photos: &Path, args: &[&str], out: &Path) -> std::process::Output {
    let mut all = vec![command, "--photos", photos.to_str().unwrap()];
    all.extend(args);
    all.extend(["--out", out.to_str().unwrap()]);
    postflight(&all, out.parent().unwrap())
}

/// The simulator's map as a UTM LAZ in `dir` (laspy, PROJ); `--no-crs`
/// in `extra` leaves its CRS out.
fn laz_map(sim: &Path, dir: &Path, extra: &[&str]) -> PathBuf {
    let laz = dir.join(if extra.is_empty() {
        "map.laz"
    } else {
        "no-crs.laz"
    });
    let ply = sim.join("map.ply");
    let mut args = vec![
        ply.to_str().unwrap(),
        laz.to_str().unwrap(),
        ORIGIN,
        UTM_32N,
    ];
    args.extend(extra);
    python_fixture("write_laz.py", &args);
    laz
}

/// Points of a map frame (`origin`: LAT,LON,ALT[,YAW_DEG]) in Earth-centred
/// coordinates, by PROJ.
fn on_earth(origin: &str, points: &[[f64; 3]]) -> Vec<Point3<f64>> {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("points.json");
    std::fs::write(&input, serde_json::to_string(points).unwrap()).unwrap();
    let out = python_fixture("to_ecef.py", &[origin, input.to_str().unwrap()]);
    let out: Vec<[f64; 3]> = serde_json::from_str(&out).unwrap();
    out.into_iter().map(Point3::from).collect()
}

/// `ingest.json`'s geo origin as `LAT,LON,ALT,YAW_DEG`.
fn recorded_origin(run: &Path) -> String {
    let o = &read_json(&run.join("ingest.json"))["geo_origin"]["origin"];
    let v = |k: &str| f(&o[k]);
    format!(
        "{},{},{},{}",
        v("latitude_deg"),
        v("longitude_deg"),
        v("altitude_m"),
        v("yaw_deg")
    )
}

/// Every truth crack's centre line, 5 mm apart, in the world frame.
fn crack_samples(sim: &Path) -> Vec<[f64; 3]> {
    let truth = read_json(&sim.join("truth.json"));
    let mut samples = Vec::new();
    for crack in truth["cracks"].as_array().unwrap() {
        for line in crack["lines"].as_array().unwrap() {
            let points: Vec<[f64; 3]> = line.as_array().unwrap().iter().map(vec3).collect();
            for pair in points.windows(2) {
                let (a, b) = (Point3::from(pair[0]), Point3::from(pair[1]));
                let steps = ((b - a).norm() / 0.005).ceil().max(1.0) as usize;
                for k in 0..=steps {
                    let p = a + (b - a) * (k as f64 / steps as f64);
                    samples.push([p.x, p.y, p.z]);
                }
            }
        }
    }
    samples
}

/// Each candidate of `run`'s distance from the nearest truth crack of
/// `sim`, compared on the Earth: the run's through its recorded geo
/// origin, the truth's through the origin the photos were tagged at, each
/// by PROJ.
fn crack_distances(run: &Path, sim: &Path) -> Vec<f64> {
    let found = candidates(run);
    let found_on_earth = on_earth(&recorded_origin(run), &found);
    let cracks_on_earth = on_earth(ORIGIN, &crack_samples(sim));
    let nearest = |p: &Point3<f64>| {
        let distances = cracks_on_earth.iter().map(|s| (s - p).norm());
        distances.fold(f64::INFINITY, f64::min)
    };
    found_on_earth.iter().map(nearest).collect()
}

/// Every candidate of `run` within `metres` of a truth crack of `sim`
/// ([`crack_distances`]); returns how many there are.
fn candidates_on_cracks(run: &Path, sim: &Path, metres: f64) -> usize {
    let distances = crack_distances(run, sim);
    for d in &distances {
        assert!(
            *d <= metres,
            "a candidate is {d:.3} m from the nearest crack: {distances:?}"
        );
    }
    let worst = distances.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "{} candidates, the farthest {worst:.3} m from its crack",
        distances.len()
    );
    distances.len()
}

/// The candidates of `run` that are of a crack (within 0.3 m of one, as
/// the localisation tests count them), each within `metres`; returns
/// (how many are of cracks, how many are elsewhere).
fn candidates_by_crack(run: &Path, sim: &Path, metres: f64) -> (usize, usize) {
    let distances = crack_distances(run, sim);
    let of_cracks: Vec<f64> = distances.iter().copied().filter(|d| *d <= 0.3).collect();
    for d in &of_cracks {
        assert!(
            *d <= metres,
            "a candidate of a crack is {d:.3} m from it: {distances:?}"
        );
    }
    (of_cracks.len(), distances.len() - of_cracks.len())
}

/// Each frame's photo and camera position, in frame order.
fn photo_positions(run: &Path) -> Vec<(String, [f64; 3])> {
    let frames = read_parquet(&run.join("frames.parquet"));
    let column = |c: &str| -> Vec<f64> {
        let values = frames.column(c).unwrap().f64().unwrap();
        values.into_no_null_iter().collect()
    };
    let (x, y, z) = (column("x"), column("y"), column("z"));
    let names = frames.column("photo").unwrap().str().unwrap().clone();
    let names = names.iter().map(|n| n.unwrap_or_default().to_string());
    names
        .zip((0..x.len()).map(|i| [x[i], y[i], z[i]]))
        .collect()
}

fn candidates(run: &Path) -> Vec<[f64; 3]> {
    let defects = read_json(&run.join("defects.json"));
    let defects = defects["defects"].as_array().unwrap();
    defects.iter().map(|d| vec3(&d["position"])).collect()
}

#[test]
fn a_dji_photo_folder_with_a_utm_laz_runs_like_its_recording() {
    let sim = simulated(&[]);
    let dir = tempfile::tempdir().unwrap();
    let (photos, listed) = photo_folder(&sim, dir.path(), &[]);
    let laz = laz_map(&sim, dir.path(), &[]);
    // The plan is in the simulator's frame: pose the photos there.
    let config = dir.path().join("photos.toml");
    let values = ORIGIN.replace(',', ", ");
    std::fs::write(&config, format!("[ingest]\nphoto_origin = [{values}]\n")).unwrap();
    let (by_photos, by_mcap) = (dir.path().join("photos-run"), dir.path().join("mcap-run"));
    let plan = sim.join("plan.json");
    let args = [
        "--map",
        laz.to_str().unwrap(),
        "--plan",
        plan.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
    ];
    let out = on_photos("run", &photos, &args, &by_photos);
    assert!(out.status.success(), "{}", stderr(&out));
    run_simulated(&sim, &by_mcap);

    // Every photo posed, within the noise of its true position.
    let ingest = read_json(&by_photos.join("ingest.json"));
    let photos_listed = listed.as_array().unwrap().len() as u64;
    assert_eq!(ingest["frames_with_pose"].as_u64(), Some(photos_listed));
    assert_eq!(
        ingest["recordings"][0]["photos"]["rtk_fixed"].as_u64(),
        Some(photos_listed)
    );

    // Every candidate on a truth crack, compared on the Earth.
    let found = candidates_on_cracks(&by_photos, &sim, 0.10);
    let mcap_found = candidates(&by_mcap).len();
    assert_eq!(found, mcap_found, "candidates: photos, recording");

    // Coverage within 1% of the recording's.
    let coverage = |run: &Path| f(&read_json(&run.join("coverage.json"))["inspected_voxels"]);
    let (photo_voxels, mcap_voxels) = (coverage(&by_photos), coverage(&by_mcap));
    assert!(
        (photo_voxels - mcap_voxels).abs() <= 0.01 * mcap_voxels,
        "inspected voxels: photos {photo_voxels}, recording {mcap_voxels}"
    );
    eprintln!("inspected voxels: photos {photo_voxels}, recording {mcap_voxels}");

    // The camera's blur the photos show, and where it came from: as the
    // recording's frames show it.
    let blur = |run: &Path| read_json(&run.join("localise.json"))["widths"].clone();
    let (photo_blur, mcap_blur) = (blur(&by_photos), blur(&by_mcap));
    assert_eq!(photo_blur["blur_from"], mcap_blur["blur_from"]);
    assert_ne!(photo_blur["blur_from"], "unknown");
    let (p, m) = (f(&photo_blur["blur_px"]), f(&mcap_blur["blur_px"]));
    assert!(
        (p / m - 1.0).abs() <= 0.25,
        "blur: photos {p} px, recording {m} px"
    );

    dji_missions_follow_wpml_and_the_plan(&by_photos);
}

/// The follow-up flight of a photo run as DJI waypoint missions, one per
/// sortie: each passes the WPML check written from DJI's documentation
/// (with djikmz's aircraft and camera enumerations), holds every
/// waypoint of its sortie with its heading, gimbal pitch and a photo, and
/// puts it within 1 cm of where PROJ puts replan.json's waypoint.
fn dji_missions_follow_wpml_and_the_plan(run: &Path) {
    for (aircraft, dji) in [("m3e", "M3E"), ("m350-h20t", "M350:H20T")] {
        let out = postflight(
            &[
                "replan",
                "--run",
                run.to_str().unwrap(),
                "--max-gimbal-up",
                "35",
                "--dji-aircraft",
                aircraft,
                "--max-sortie-length",
                "120",
                "--solver-time-limit",
                "2",
            ],
            run.parent().unwrap(),
        );
        assert!(out.status.success(), "{}", stderr(&out));
        let plan = read_json(&run.join("replan.json"));
        let sorties = plan["sorties"].as_array().unwrap();
        assert!(sorties.len() > 1, "the 120 m limit splits the flight");
        for (k, sortie) in sorties.iter().enumerate() {
            for w in sortie["waypoints"].as_array().unwrap() {
                let up = -f(&w["gimbal_pitch"]).to_degrees();
                assert!(up <= 35.0 + 1e-9, "a waypoint looks {up:.1} degrees up");
            }
            let kmz = run.join(format!("replan-{}.kmz", k + 1));
            let checked = python_fixture(
                "check_wpml.py",
                &[
                    kmz.to_str().unwrap(),
                    run.join("replan.json").to_str().unwrap(),
                    &k.to_string(),
                    dji,
                ],
            );
            let checked: Value = serde_json::from_str(&checked).unwrap();
            let waypoints = sortie["waypoints"].as_array().unwrap().len() as u64;
            assert_eq!(checked["photos"].as_u64(), Some(waypoints), "{checked}");
            assert!(f(&checked["worst_m"]) < 0.01, "{checked}");
        }
        eprintln!("{aircraft}: {} sorties as DJI missions", sorties.len());
    }
}

/// COLMAP (pycolmap) reconstructs a textured simulated flight's photos on
/// its own (SIFT, sequential matching, incremental mapping, the camera
/// held at its calibration, in a frame and scale of its own). The photos
/// carry GPS but no orientation, so only the reconstruction can pose them:
/// postflight fits it to their GPS, poses the photos it registered, and
/// every candidate of a crack lands within 15 cm of it on the Earth. The
/// same model as text poses them the same, and as OpenSfM's
/// `reconstruction.json` on the Earth by its reference, within 5 cm of
/// the truth.
#[test]
fn a_colmap_reconstruction_fitted_to_the_photos_gps_places_the_cracks() {
    let sim = simulated(&["--textured"]);
    let dir = tempfile::tempdir().unwrap();
    let (photos, _) = photo_folder(&sim, dir.path(), &["--no-gimbal"]);
    let (model, text) = (dir.path().join("sparse"), dir.path().join("sparse-text"));
    let truth = read_json(&sim.join("truth.json"));
    let k = &truth["camera"];
    let d: Vec<f64> = k["distortion"]["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    // COLMAP's pixel centres are at half-integers.
    let camera = format!(
        "{},{},{},{},{},{},{},{}",
        f(&k["fx"]),
        f(&k["fy"]),
        f(&k["cx"]) + 0.5,
        f(&k["cy"]) + 0.5,
        d[0],
        d[1],
        d[2],
        d[3]
    );
    let made = python_fixture(
        "colmap_sfm.py",
        &[
            photos.to_str().unwrap(),
            model.to_str().unwrap(),
            "--camera",
            &camera,
            "--text-copy",
            text.to_str().unwrap(),
        ],
    );
    let made: Value = serde_json::from_str(&made).unwrap();
    let registered = made["images"].as_u64().unwrap();
    assert!(registered >= 30, "COLMAP registered {made}");
    let laz = laz_map(&sim, dir.path(), &[]);
    let run = dir.path().join("binary");
    let config = dir.path().join("reconstruction.toml");
    let values = ORIGIN.replace(',', ", ");
    let model_path = model.to_str().unwrap();
    let settings =
        format!("[ingest]\nphoto_origin = [{values}]\nreconstruction = {model_path:?}\n");
    std::fs::write(&config, settings).unwrap();
    let args = [
        "--map",
        laz.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
    ];
    let out = on_photos("run", &photos, &args, &run);
    assert!(out.status.success(), "{}", stderr(&out));
    let ingest = read_json(&run.join("ingest.json"));
    let r = &ingest["reconstruction"];
    assert_eq!(r["format"], "colmap");
    assert_eq!(r["posed"].as_u64(), Some(registered), "{r}");
    assert_eq!(ingest["frames_with_pose"].as_u64(), Some(registered));
    assert_eq!(r["placed_by"]["kind"], "gps_fit");
    // The photos' GPS carries 2 cm of noise per axis.
    let rms = f(&r["placed_by"]["rms_m"]);
    assert!(
        rms < 0.06,
        "the model's cameras sit {rms:.3} m RMS from the photos' GPS"
    );
    eprintln!(
        "COLMAP registered {registered} photos; fitted to their GPS at {:.1} cm RMS, scale {:.3}",
        rms * 100.0,
        f(&r["similarity"]["scale"])
    );
    let (on_cracks, off) = candidates_by_crack(&run, &sim, 0.15);
    // The lens's blur hides the faintest of the photos' cracks.
    assert!(on_cracks >= 2, "{on_cracks} candidates of cracks");
    // Without a map, the reconstruction's points are the map.
    let out = postflight(&["localise", "--run", run.to_str().unwrap()], dir.path());
    assert!(out.status.success(), "{}", stderr(&out));
    let localised = read_json(&run.join("localise.json"));
    assert_eq!(localised["map_points"], made["points"]);
    assert!(
        localised["map"]
            .as_str()
            .unwrap()
            .starts_with("reconstruction ")
    );
    eprintln!("{on_cracks} candidates of cracks, {off} elsewhere (the textured surface's)");

    // The text model poses them the same; the model as OpenSfM's
    // reconstruction.json, georeferenced (by the truth), by its reference.
    let truth_positions: serde_json::Map<String, Value> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| !f["dropped"].as_bool().unwrap())
        .enumerate()
        .map(|(i, f)| {
            (
                format!("DJI_{:04}.JPG", i + 1),
                f["camera_pose"]["translation"].clone(),
            )
        })
        .collect();
    let positions = dir.path().join("positions.json");
    std::fs::write(
        &positions,
        Value::Object(truth_positions.clone()).to_string(),
    )
    .unwrap();
    let opensfm = dir.path().join("reconstruction.json");
    python_fixture(
        "colmap_to_opensfm.py",
        &[
            model.to_str().unwrap(),
            opensfm.to_str().unwrap(),
            ORIGIN,
            positions.to_str().unwrap(),
        ],
    );
    let ingest_with = |model: &Path, name: &str| {
        let run = dir.path().join(name);
        let model = model.to_str().unwrap();
        let args = ["--photo-origin", ORIGIN, "--reconstruction", model];
        let out = on_photos("ingest", &photos, &args, &run);
        assert!(out.status.success(), "{}", stderr(&out));
        run
    };
    let binary = photo_positions(&run);
    let text = photo_positions(&ingest_with(&text, "text"));
    assert_eq!(binary.len(), text.len());
    for ((a, p), (b, q)) in binary.iter().zip(&text) {
        assert_eq!(a, b);
        assert!((Point3::from(*p) - Point3::from(*q)).norm() < 1e-6, "{a}");
    }
    let by_reference = ingest_with(&opensfm, "opensfm");
    let r = &read_json(&by_reference.join("ingest.json"))["reconstruction"];
    assert_eq!(
        (&r["format"], &r["placed_by"]["kind"]),
        (&"opensfm".into(), &"reference".into())
    );
    let mut worst: f64 = 0.0;
    for (name, p) in photo_positions(&by_reference) {
        let truth = Point3::from(vec3(&truth_positions[&name]));
        worst = worst.max((Point3::from(p) - truth).norm());
    }
    assert!(
        worst < 0.05,
        "a photo posed by OpenSfM's model is {worst:.3} m from the truth"
    );
    eprintln!(
        "posed by the OpenSfM model, the farthest photo {:.1} cm from the truth",
        worst * 100.0
    );
}

#[test]
fn without_a_given_origin_photos_are_posed_at_the_first_photo() {
    let sim = simulated(&["--frames", "60"]);
    let dir = tempfile::tempdir().unwrap();
    let (photos, listed) = photo_folder(&sim, dir.path(), &["--noise", "0"]);
    let run = dir.path().join("run");
    let out = postflight(
        &[
            "ingest",
            "--flight",
            photos.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let origin = &read_json(&run.join("ingest.json"))["geo_origin"]["origin"];
    let first = &listed[0];
    assert!((f(&origin["latitude_deg"]) - f(&first["latitude"])).abs() < 1e-9);
    assert!((f(&origin["longitude_deg"]) - f(&first["longitude"])).abs() < 1e-9);
    // Each frame's camera, through the recorded origin, where its photo
    // was taken (the truth, through PROJ both ways).
    let posed: Vec<[f64; 3]> = photo_positions(&run).into_iter().map(|(_, p)| p).collect();
    let truth = read_json(&sim.join("truth.json"));
    let true_positions: Vec<[f64; 3]> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| !f["dropped"].as_bool().unwrap())
        .map(|f| vec3(&f["camera_pose"]["translation"]))
        .collect();
    assert_eq!(posed.len(), true_positions.len());
    let (a, b) = (
        on_earth(&recorded_origin(&run), &posed),
        on_earth(ORIGIN, &true_positions),
    );
    for (p, t) in a.iter().zip(&b) {
        assert!((p - t).norm() < 0.002, "{p} against {t}");
    }
}

#[test]
fn bad_photos_and_a_laz_without_a_crs_are_named_in_one_line() {
    let sim = simulated(&["--frames", "60"]);
    let dir = tempfile::tempdir().unwrap();
    let (photos, _) = photo_folder(
        &sim,
        dir.path(),
        &["--skip-gps", "DJI_0003.JPG", "--corrupt", "DJI_0007.JPG"],
    );
    // Skipped, a warning each.
    let run = dir.path().join("skipped");
    let out = on_photos("ingest", &photos, &[], &run);
    assert!(out.status.success(), "{}", stderr(&out));
    let warnings = ingest_warnings(&run);
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("DJI_0003.JPG: no GPS position")),
        "{warnings:?}"
    );
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("DJI_0007.JPG: it is not a readable JPEG")),
        "{warnings:?}"
    );
    // Refused with --strict, in one line, with nothing written.
    let run = dir.path().join("strict");
    let out = on_photos("ingest", &photos, &["--strict"], &run);
    assert!(!out.status.success());
    let error = stderr(&out);
    assert_eq!(error.trim().lines().count(), 1, "{error}");
    assert!(
        error.contains("DJI_0003.JPG cannot be used: no GPS position")
            && error.contains("--strict"),
        "{error}"
    );
    assert!(!run.exists());

    // A LAZ without a CRS: refused before anything is written.
    let laz = laz_map(&sim, dir.path(), &["--no-crs"]);
    let run = dir.path().join("no-crs");
    let out = on_photos("run", &photos, &["--map", laz.to_str().unwrap()], &run);
    assert!(!out.status.success());
    let error = stderr(&out);
    assert_eq!(error.trim().lines().count(), 1, "{error}");
    assert!(
        error.contains("no-crs.laz") && error.contains("no coordinate reference system"),
        "{error}"
    );
    assert!(!run.exists());
}

/// Tags and reconstructions holding values no camera or solver writes
/// (issue 57, items 1, 2 and 12): each photo so tagged is skipped with the
/// tag named, each reconstruction refused in one line with the value
/// named, within seconds, and nothing written.
#[test]
fn tags_and_reconstructions_that_are_no_cameras_are_named() {
    let sim = simulated(&["--frames", "60"]);
    let dir = tempfile::tempdir().unwrap();
    let bad = [
        (
            "DJI_0002.JPG",
            "XMP-drone-dji:AbsoluteAltitude=1e308",
            "altitude 1e308 m is not a flight's",
        ),
        ("DJI_0003.JPG", "GPSLatitude=200", "200"),
        (
            "DJI_0004.JPG",
            "XMP-drone-dji:GimbalYawDegree=1e300",
            "gimbal angles",
        ),
        (
            "DJI_0005.JPG",
            "XMP-drone-dji:DewarpData=2026-01-01;inf,inf,0,0,0,0,0,0,0",
            "DewarpData is not a lens's",
        ),
        (
            "DJI_0006.JPG",
            "XMP-drone-dji:DewarpData=2026-01-01;3000,3000,1e9,0,0,0,0,0,0",
            "principal point",
        ),
        (
            "DJI_0007.JPG",
            "XMP-drone-dji:DewarpData=2026-01-01;3000,3000,0,0,1e300,0,0,0,0",
            "distortion coefficient",
        ),
    ];
    let mut extra = Vec::new();
    for (name, tag, _) in &bad {
        extra.extend(["--retag", name, tag]);
    }
    let (photos, _) = photo_folder(&sim, dir.path(), &extra);
    // A copy cut short: its header reads, its image does not.
    let whole = std::fs::read(photos.join("DJI_0008.JPG")).unwrap();
    std::fs::write(photos.join("DJI_0008.JPG"), &whole[..whole.len() / 2]).unwrap();
    let run = dir.path().join("skipped");
    let out = on_photos("ingest", &photos, &[], &run);
    assert!(out.status.success(), "{}", stderr(&out));
    let warnings = ingest_warnings(&run);
    let truncated = ("DJI_0008.JPG", "", "it is truncated");
    for (name, _, says) in bad.iter().chain([&truncated]) {
        assert!(
            warnings
                .iter()
                .any(|w| w.starts_with(&format!("{name}: ")) && w.contains(says)),
            "{name}: {says} in {warnings:?}"
        );
    }
    // A folder whose only photo is one of them: its error is that photo's,
    // not "no GPS position".
    let alone = dir.path().join("alone");
    std::fs::create_dir_all(&alone).unwrap();
    std::fs::copy(photos.join(bad[0].0), alone.join(bad[0].0)).unwrap();
    let out = on_photos("ingest", &alone, &[], &dir.path().join("alone-run"));
    assert_fails_in_one_line(&out, bad[0].2);

    // Reconstructions: an OpenSfM reference far off the Earth (a hang in
    // the rotation's iteration before), a COLMAP lens that is no lens.
    let opensfm = |reference: &str, camera: &str| {
        format!(
            r#"[{{"cameras": {{"c": {camera}}}, "shots": {{"DJI_0001.JPG": {{"camera": "c", "rotation": [0, 0, 0], "translation": [0, 0, 0]}}}}, "points": {{}}, "reference_lla": {reference}}}]"#
        )
    };
    let lens = r#"{"projection_type": "perspective", "width": 1280, "height": 960, "focal": 2.0}"#;
    let here = r#"{"latitude": 47.3977, "longitude": 8.5456, "altitude": 488}"#;
    let colmap = |i: usize, cameras: &str| {
        let model = dir.path().join(format!("colmap-{i}"));
        std::fs::create_dir_all(&model).unwrap();
        std::fs::write(model.join("cameras.txt"), cameras).unwrap();
        std::fs::write(
            model.join("images.txt"),
            "1 1 0 0 0 0 0 0 1 DJI_0001.JPG\n\n",
        )
        .unwrap();
        std::fs::write(model.join("points3D.txt"), "").unwrap();
        model
    };
    let refused = [
        (
            opensfm(
                r#"{"latitude": 47.3977, "longitude": 8.5456, "altitude": 1e308}"#,
                lens,
            ),
            None,
            "its reference_lla is not a place on the Earth: altitude 1e308 m",
        ),
        (
            opensfm(
                r#"{"latitude": 999, "longitude": 8.5456, "altitude": 488}"#,
                lens,
            ),
            None,
            "999,8.5456 is not a latitude and longitude",
        ),
        (
            opensfm(
                here,
                r#"{"projection_type": "perspective", "width": 1280, "height": 960, "focal": 0}"#,
            ),
            None,
            "focal length 0 x 0 px",
        ),
        (
            opensfm(
                here,
                r#"{"projection_type": "perspective", "width": -1280, "height": 960, "focal": 2}"#,
            ),
            None,
            "a camera -1280 x 960 pixels",
        ),
        (
            String::new(),
            Some("1 PINHOLE 1280 960 3000 640 480\n"),
            "PINHOLE has 3 parameters; COLMAP's PINHOLE has 4",
        ),
        (
            String::new(),
            Some("1 PINHOLE 1280 960 0 3000 640 480\n"),
            "focal length 0 x 3000 px",
        ),
        (
            String::new(),
            Some("1 PINHOLE 1280 960 -300 -300 640 480\n"),
            "focal length -300 x -300 px",
        ),
        (
            String::new(),
            Some("1 SIMPLE_RADIAL 1280 960 3000 640 480 1e300\n"),
            "distortion coefficient 1e300",
        ),
        (
            String::new(),
            Some("1 PINHOLE 1280 960 nan 3000 640 480\n"),
            "focal length NaN x 3000 px",
        ),
    ];
    let (photos, _) = photo_folder(&sim, &dir.path().join("good"), &[]);
    for (i, (json, cameras, says)) in refused.iter().enumerate() {
        let model = match cameras {
            Some(cameras) => colmap(i, cameras),
            None => {
                let path = dir.path().join(format!("reconstruction-{i}.json"));
                std::fs::write(&path, json).unwrap();
                path
            }
        };
        let run = dir.path().join(format!("refused-{i}"));
        let started = std::time::Instant::now();
        let out = on_photos(
            "ingest",
            &photos,
            &["--reconstruction", model.to_str().unwrap()],
            &run,
        );
        assert!(
            started.elapsed().as_secs() < 30,
            "{says}: {:?}",
            started.elapsed()
        );
        assert_fails_in_one_line(&out, says);
        assert!(!run.join("ingest.json").exists(), "{says}");
    }
    // Into a run ingested before: the failure leaves no ingest.json that
    // claims the earlier flight is this one (issue 57, item 13).
    let earlier = dir.path().join("skipped");
    assert!(earlier.join("ingest.json").is_file());
    let bad = dir.path().join("reconstruction-0.json");
    let out = on_photos(
        "ingest",
        &photos,
        &["--reconstruction", bad.to_str().unwrap()],
        &earlier,
    );
    assert_fails_in_one_line(&out, refused[0].2);
    assert!(!earlier.join("ingest.json").exists());
}
