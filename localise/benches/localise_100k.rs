//! Localisation speed: 100k detections against a 1M-point map, and the
//! obvious alternative on the same rays (marching along each ray in 5 cm
//! steps, asking the KD-tree for the nearest map point at each step).
//!
//! `cargo bench -p postflight-localise --bench localise_100k`

use std::time::Instant;

use localise::LocaliseConfig;
use localise::fusion::fuse;
use localise::observation::{Observation, Scene};
use localise::trace::CrackTrace;
use nalgebra::{Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::FrameDetection;
use postflight_core::detection::{BoxXyxy, Detection};
use postflight_core::map::{PointCloud, SlamMap};
use postflight_core::outputs::localise::Outcome;
use postflight_core::{Distortion, Intrinsics};
use rayon::prelude::*;
use sim::rng::Rng;

const MAP_POINTS: usize = 1_000_000;
const DETECTIONS: usize = 100_000;
const CRACKS: usize = 500;
const MARCH_STEP: f64 = 0.05;
const MARCH_HIT: f64 = 0.05;

/// A 200 m box girder, 4 m wide and 3 m deep, on piers every 25 m: its
/// surfaces sampled with 1.5 cm noise.
fn girder_map(rng: &mut Rng) -> SlamMap {
    let mut points = Vec::with_capacity(MAP_POINTS);
    let faces: [(Point3<f64>, Vector3<f64>, Vector3<f64>); 4] = [
        (
            Point3::new(0.0, -2.0, 10.0),
            Vector3::x() * 200.0,
            Vector3::z() * 3.0,
        ),
        (
            Point3::new(0.0, 2.0, 10.0),
            Vector3::x() * 200.0,
            Vector3::z() * 3.0,
        ),
        (
            Point3::new(0.0, -2.0, 10.0),
            Vector3::x() * 200.0,
            Vector3::y() * 4.0,
        ),
        (
            Point3::new(0.0, -2.0, 13.0),
            Vector3::x() * 200.0,
            Vector3::y() * 4.0,
        ),
    ];
    let piers = 8;
    let per_pier = MAP_POINTS / 10 / piers;
    for k in 0..piers {
        let x = 12.5 + 25.0 * k as f64;
        for _ in 0..per_pier {
            let a = rng.uniform() * std::f64::consts::TAU;
            let z = rng.uniform() * 10.0;
            points.push(Point3::new(x + a.cos() * 0.8, a.sin() * 0.8, z));
        }
    }
    while points.len() < MAP_POINTS {
        let (o, u, v) = faces[(rng.uniform() * 4.0) as usize];
        let p = o + u * rng.uniform() + v * rng.uniform();
        let noise = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.015;
        points.push(p + noise);
    }
    SlamMap::new(
        PointCloud {
            frame_id: "map".into(),
            points,
            grid: None,
            mesh_spacing_m: None,
        },
        0.5,
    )
    .expect("points")
}

/// A camera 3.5 m from a side of the girder, looking at it, at `x` along it.
fn camera(i: usize, x: f64, rng: &mut Rng) -> Isometry3<f64> {
    let side = if i.is_multiple_of(2) { -1.0 } else { 1.0 };
    let position = Point3::new(x, side * 5.5, 11.5 + rng.normal() * 0.3);
    let forward = Vector3::new(0.0, -side, 0.0);
    // Optical frame: z forward, y down, x right.
    let down = -Vector3::z();
    let right = down.cross(&forward);
    let rotation = nalgebra::Rotation3::from_basis_unchecked(&[right, down, forward]);
    Isometry3::from_parts(
        Translation3::from(position.coords),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// Cracks on the girder's two sides: random walks of 12 steps of 3 cm,
/// starting at least 0.9 m apart so each is one candidate.
fn cracks(rng: &mut Rng) -> Vec<Vec<Point3<f64>>> {
    let mut cracks: Vec<Vec<Point3<f64>>> = Vec::new();
    while cracks.len() < CRACKS {
        let line = {
            let i = cracks.len();
            let side = if i.is_multiple_of(2) { -2.0 } else { 2.0 };
            let mut p = Point3::new(
                1.0 + rng.uniform() * 198.0,
                side,
                10.4 + rng.uniform() * 2.2,
            );
            let mut heading = rng.uniform() * std::f64::consts::TAU;
            let mut line = vec![p];
            for _ in 0..12 {
                heading += rng.normal() * 0.3;
                p += Vector3::new(heading.cos(), 0.0, heading.sin()) * 0.03;
                line.push(p);
            }
            line
        };
        if cracks.iter().all(|c| (c[0] - line[0]).norm() > 0.9) {
            cracks.push(line);
        }
    }
    cracks
}

/// A crack as a camera sees it: its line projected, a pixel apart; `None`
/// unless it is wholly in view and faces the camera.
fn trace(pose: &Isometry3<f64>, k: &Intrinsics, crack: &[Point3<f64>]) -> Option<CrackTrace> {
    let to_camera = pose.inverse();
    let mut pixels: Vec<Point2<f64>> = Vec::new();
    for w in crack.windows(2) {
        let a = k.project(&(to_camera * w[0]).coords)?;
        let b = k.project(&(to_camera * w[1]).coords)?;
        let steps = (b - a).norm().ceil().max(1.0) as usize;
        pixels.extend((0..steps).map(|s| a + (b - a) * (s as f64 / steps as f64)));
    }
    let inside = |p: &Point2<f64>| {
        p.x > 4.0 && p.y > 4.0 && p.x < f64::from(k.width) - 4.0 && p.y < f64::from(k.height) - 4.0
    };
    if !pixels.iter().all(inside) || (crack[0].y * pose.translation.y) < 0.0 {
        return None;
    }
    let edges = (0..pixels.len() as u32 - 1).map(|i| (i, i + 1)).collect();
    Some(CrackTrace {
        pixels,
        edges,
        bridges: Vec::new(),
    })
}

fn detection(frame: u32, t: &CrackTrace) -> FrameDetection {
    let (lo, hi) = t.pixels.iter().fold(
        (
            Point2::new(f64::MAX, f64::MAX),
            Point2::new(f64::MIN, f64::MIN),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    FrameDetection {
        frame,
        time_ns: i64::from(frame),
        detection: Detection {
            bbox: BoxXyxy {
                x0: lo.x as f32,
                y0: lo.y as f32,
                x1: hi.x as f32,
                y1: hi.y as f32,
            },
            score: 0.6,
            class: 0,
            kind: DefectKind::Crack,
            tile: -1,
            mask: None,
        },
    }
}

/// The obvious way: march along the ray in fixed steps, asking the KD-tree
/// for the nearest map point at every step, until one is close. With
/// `skip`, steps lengthen to the nearest point's distance (sphere tracing).
fn march(
    map: &SlamMap,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    max_range: f64,
    skip: bool,
) -> Option<f64> {
    let mut t = 0.0;
    while t < max_range {
        let n = map.nearest(&(origin + dir * t));
        if n.distance < MARCH_HIT {
            return Some(t);
        }
        t += if skip {
            MARCH_STEP.max(n.distance - MARCH_HIT)
        } else {
            MARCH_STEP
        };
    }
    None
}

fn main() {
    let threads = rayon::current_num_threads();
    let mut rng = Rng::new(0x5EED);
    let start = Instant::now();
    let map = girder_map(&mut rng);
    println!(
        "map: {} points, {} voxels, built in {:.1} s",
        map.cloud.len(),
        map.voxels.len(),
        start.elapsed().as_secs_f64()
    );
    let k = Intrinsics {
        distortion: Distortion::PlumbBob([-0.08, 0.025, 0.0004, -0.0003, 0.0]),
        ..Intrinsics::pinhole(640, 480, 960.0)
    };
    let cracks = cracks(&mut rng);
    // Frames along both sides until the cracks in view add up to 100k detections.
    let mut work: Vec<(Isometry3<f64>, FrameDetection, CrackTrace)> = Vec::new();
    let mut frames = 0;
    let mut in_view = std::collections::BTreeSet::new();
    'flight: for pass in 0.. {
        for i in 0..2000 {
            let x = 200.0 * (i as f64 + 0.25 + 0.5 * f64::from(pass % 2)) / 2000.0;
            let pose = camera(i + pass as usize, x, &mut rng);
            frames += 1;
            for c in cracks.iter().filter(|c| (c[0].x - x).abs() < 1.5) {
                if let Some(t) = trace(&pose, &k, c) {
                    in_view.insert(c[0].x.to_bits());
                    work.push((pose, detection(frames, &t), t));
                    if work.len() == DETECTIONS {
                        break 'flight;
                    }
                }
            }
        }
    }
    let scene = Scene {
        map: &map,
        structure: None,
        max_range: 30.0,
        view: &postflight_core::ViewModel::default(),
    };

    let start = Instant::now();
    let observations: Vec<Observation> = work
        .par_iter()
        .map(|(pose, d, t)| scene.place(d.clone(), pose, &k, Some(t), Vec::new(), None))
        .collect();
    let placing = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let candidates = fuse(&observations, &LocaliseConfig::default());
    let fusing = start.elapsed().as_secs_f64();
    let placed = observations
        .iter()
        .filter(|o| o.outcome == Outcome::Placed)
        .count();
    let ours = placing + fusing;
    let seen: std::collections::BTreeSet<usize> =
        work.iter().map(|(_, d, _)| d.frame as usize).collect();
    println!(
        "{} frames, {} with detections; {} cracks, {} of them in view",
        frames,
        seen.len(),
        cracks.len(),
        in_view.len()
    );
    println!(
        "postflight: {} detections placed ({placed} on the map) in {placing:.2} s, fused into {} candidates in {fusing:.2} s: {:.2} s, {:.0} detections/s on {threads} threads",
        observations.len(),
        candidates.len(),
        ours,
        observations.len() as f64 / ours
    );

    // The alternatives on a sample of the same detections, casting the
    // same 7 rays per detection (they find only a point: no plane, normal
    // or edge check), scaled to all of them.
    let sample = 2_000;
    for (name, skip) in [
        ("ray marching, 5 cm steps, KD-tree nearest point", false),
        ("sphere tracing with KD-tree nearest point", true),
    ] {
        let start = Instant::now();
        let hits: usize = work[..sample]
            .par_iter()
            .map(|(pose, _, t)| {
                let origin = Point3::from(pose.translation.vector);
                (0..7)
                    .filter(|j| {
                        let px = t.pixels[j * (t.pixels.len() - 1) / 6];
                        let dir = pose.rotation * k.ray(&px);
                        march(&map, &origin, &dir, 30.0, skip).is_some()
                    })
                    .count()
            })
            .sum();
        let per = start.elapsed().as_secs_f64() / sample as f64;
        let all = per * work.len() as f64;
        println!(
            "{name}: {sample} detections ({hits} of {} rays hit) in {:.2} s, so {all:.1} s for all {}: {:.2}x postflight's time",
            sample * 7,
            per * sample as f64,
            work.len(),
            all / ours
        );
    }
}
