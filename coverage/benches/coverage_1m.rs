//! Coverage of 1M occupied voxels by 10k frames, against the naive
//! every-frame-against-every-face search on the same input.
//!
//! The structure is ten parallel walls, 500 m long, 50 m tall and one voxel
//! thick (0.5 m voxels, 1M voxels, 2M exposed faces), mapped with a point
//! every 25 cm. 10,000 frames fly lines 3.5 m off both sides of each wall
//! at the heights of a GATSBI-style survey, looking at the wall. The naive
//! search is timed on a fixed 1% sample of the faces (every 100th) and
//! scaled up; on that sample both searches must agree exactly.
//!
//! Run: `cargo bench -p postflight-coverage --bench coverage_1m`

use std::time::Instant;

use coverage::{Face, Shot, cover, cover_naive, exposed_faces};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid, VoxelIndex};
use postflight_core::{Intrinsics, ViewModel};

const WALLS: i32 = 10;
/// Wall spacing, voxels (20 m).
const SPACING: i32 = 40;
/// Wall length and height, voxels.
const LENGTH: i32 = 1000;
const HEIGHT: i32 = 100;
const FRAMES: usize = 10_000;

fn main() {
    let res = 0.5;
    let grid = VoxelGrid::new(res, Point3::origin());
    let targets: Vec<VoxelIndex> = (0..WALLS)
        .flat_map(|w| {
            (0..LENGTH).flat_map(move |y| (0..HEIGHT).map(move |z| VoxelIndex([w * SPACING, y, z])))
        })
        .collect();
    let mut points = Vec::with_capacity(targets.len() * 4);
    for v in &targets {
        let c = grid.center(*v);
        for (dy, dz) in [
            (-0.125, -0.125),
            (0.125, -0.125),
            (-0.125, 0.125),
            (0.125, 0.125),
        ] {
            points.push(Point3::new(c.x, c.y + dy, c.z + dz));
        }
    }
    let t = Instant::now();
    let map = SlamMap::on_grid(
        PointCloud {
            frame_id: "map".into(),
            points,
            grid: None,
            mesh_spacing_m: None,
        },
        grid,
    )
    .expect("points");
    let solid = targets.iter().copied().collect();
    let faces = exposed_faces(&grid, &targets, &solid);
    let need = vec![1; faces.len()];
    println!(
        "{} occupied voxels, {} exposed faces, {} map points; map indexed in {:.1} s",
        targets.len(),
        faces.len(),
        map.cloud.points.len(),
        t.elapsed().as_secs_f64()
    );

    let lens = Intrinsics::pinhole(1280, 960, 1100.0);
    // Frames on lines along both sides of every wall; each line at one height.
    let lines = (WALLS * 2) as usize;
    let per_line_heights = 5;
    let per_line = FRAMES / lines / per_line_heights;
    let mut shots = Vec::with_capacity(FRAMES);
    for w in 0..WALLS {
        let x = f64::from(w * SPACING) * res + res / 2.0;
        for side in [-1.0, 1.0] {
            for h in 0..per_line_heights {
                let z = 5.0 + 10.0 * h as f64;
                for i in 0..per_line {
                    let y = (i as f64 + 0.5) * f64::from(LENGTH) * res / per_line as f64;
                    let look = Vector3::new(-side, 0.0, 0.0);
                    let right = look.cross(&Vector3::z());
                    let down = look.cross(&right);
                    let m = Matrix3::from_columns(&[right, down, look]);
                    shots.push(Shot {
                        id: shots.len() as u32,
                        camera: Isometry3::from_parts(
                            Translation3::new(x + side * 3.75, y, z),
                            UnitQuaternion::from_matrix(&m),
                        ),
                        lens: 0,
                        blur_px: Some(1.0),
                    });
                }
            }
        }
    }
    let view = ViewModel::default();
    let lenses = [lens];

    let t = Instant::now();
    let culled = cover(&faces, &need, &shots, &lenses, &map, &view);
    let culled_s = t.elapsed().as_secs_f64();
    let inspected = culled.iter().filter(|c| c.miss.is_none()).count();
    println!(
        "postflight (KD-tree culling, rayon): {} frames x {} faces in {culled_s:.1} s; {inspected} faces inspected",
        shots.len(),
        faces.len()
    );

    let sample: Vec<Face> = faces.iter().step_by(100).copied().collect();
    let sample_need = vec![1; sample.len()];
    let t = Instant::now();
    let naive = cover_naive(&sample, &sample_need, &shots, &lenses, &map, &view);
    let naive_s = t.elapsed().as_secs_f64() * faces.len() as f64 / sample.len() as f64;
    let same = sample
        .iter()
        .zip(&naive)
        .enumerate()
        .all(|(i, (_, n))| *n == culled[i * 100]);
    assert!(same, "the culled and the naive search disagree");
    println!(
        "naive (every frame against every face): {naive_s:.0} s (timed on {} faces, scaled); {:.0}x slower; results identical on the sample",
        sample.len(),
        naive_s / culled_s
    );
}
