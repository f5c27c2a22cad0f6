//! Coverage of faces by a set of camera shots: every face against the
//! shots near it (a KD-tree of camera centres culls the rest), in parallel.
//! [`cover_naive`] checks every face against every shot, as the baseline
//! the benchmark compares with.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Isometry3, Point3};
use postflight_core::map::SlamMap;
use postflight_core::{Intrinsics, ViewModel};
use rayon::prelude::*;

use crate::face::Face;
use crate::view::{Miss, Sight, look, occluded};

/// One camera exposure to judge faces against: a flight frame or a plan viewpoint.
#[derive(Debug, Clone)]
pub struct Shot {
    /// Frame index, or viewpoint index for a plan.
    pub id: u32,
    /// Optical frame in the world (`T_world_camera`).
    pub camera: Isometry3<f64>,
    /// Index into the intrinsics passed with the shots.
    pub lens: usize,
    /// Blur streak, pixels (`None`: not known, not judged).
    pub blur_px: Option<f64>,
}

/// What the shots did for one face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceCover {
    /// Usable shots that inspect the face.
    pub views: u32,
    /// The inspecting view with the finest GSD, and its shot id.
    pub best: Option<(Sight, u32)>,
    /// When no usable shot inspects it: the furthest rule any shot reached.
    pub miss: Option<Miss>,
}

/// Judge one face against one shot: the View model's rules in order.
pub fn judge(
    face: &Face,
    shot: &Shot,
    lenses: &[Intrinsics],
    map: &SlamMap,
    view: &ViewModel,
) -> Result<Sight, Miss> {
    let sight = look(&shot.camera, &lenses[shot.lens], face, view)?;
    if occluded(map, &Point3::from(shot.camera.translation.vector), face) {
        return Err(Miss::Occluded);
    }
    view.blur_miss(shot.blur_px).map_or(Ok(()), Err)?;
    Ok(sight)
}

/// Judge `face` against `shots` and sum up what they did for it.
fn cover_face<'a>(
    face: &Face,
    need: u32,
    shots: impl Iterator<Item = &'a Shot>,
    lenses: &[Intrinsics],
    map: &SlamMap,
    view: &ViewModel,
) -> FaceCover {
    let results = shots.map(|shot| (shot.id, judge(face, shot, lenses, map, view)));
    let mut cover = FaceCover {
        views: 0,
        best: None,
        miss: None,
    };
    let mut furthest = Miss::TooFar;
    for (id, r) in results {
        match r {
            Ok(s) => {
                cover.views += 1;
                if cover.best.is_none_or(|(b, _)| s.gsd_mm < b.gsd_mm) {
                    cover.best = Some((s, id));
                }
            }
            Err(m) => furthest = furthest.max(m),
        }
    }
    if cover.views < need {
        cover.miss = Some(if cover.views > 0 {
            Miss::TooFewViews
        } else {
            furthest
        });
    }
    cover
}

/// Coverage of each face by `shots` (`need[i]` views make face `i` inspected).
pub fn cover(
    faces: &[Face],
    need: &[u32],
    shots: &[Shot],
    lenses: &[Intrinsics],
    map: &SlamMap,
    view: &ViewModel,
) -> Vec<FaceCover> {
    let coords: Vec<[f64; 3]> = shots
        .iter()
        .map(|s| s.camera.translation.vector.into())
        .collect();
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&coords).ok();
    let r2 = view.max_distance_m * view.max_distance_m;
    faces
        .par_iter()
        .zip(need)
        .map(|(face, &need)| {
            let Some(tree) = &tree else {
                return cover_face(face, need, std::iter::empty(), lenses, map, view);
            };
            let c = face.centre;
            let mut near: Vec<u64> = Vec::new();
            tree.query(&[c.x, c.y, c.z])
                .within::<SquaredEuclidean<f64>>(r2)
                .unsorted()
                .visit(|hit| near.push(hit.item as u64));
            // Shot order, so ties in GSD pick the same shot every run.
            near.sort_unstable();
            let near = near.into_iter().map(|i| &shots[i as usize]);
            cover_face(face, need, near, lenses, map, view)
        })
        .collect()
}

/// [`cover`] without culling: every face against every shot.
pub fn cover_naive(
    faces: &[Face],
    need: &[u32],
    shots: &[Shot],
    lenses: &[Intrinsics],
    map: &SlamMap,
    view: &ViewModel,
) -> Vec<FaceCover> {
    faces
        .par_iter()
        .zip(need)
        .map(|(face, &need)| cover_face(face, need, shots.iter(), lenses, map, view))
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use postflight_core::map::{FaceSide, PointCloud, VoxelGrid, VoxelIndex};

    /// A wall in the plane x = 0 (voxel column x = 0 facing +x), cameras
    /// 3.5 m out looking back at it, and the faces of the wall.
    pub(crate) fn scene() -> (Vec<Face>, SlamMap, Vec<Intrinsics>) {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let points: Vec<Point3<f64>> = (0..40)
            .flat_map(|y| {
                (0..20).map(move |z| Point3::new(0.45, f64::from(y) * 0.125, f64::from(z) * 0.125))
            })
            .collect();
        let faces = (0..10)
            .flat_map(|y| (0..5).map(move |z| VoxelIndex([0, y, z])))
            .map(|v| Face::new(&grid, v, FaceSide::PosX))
            .collect();
        let map = SlamMap::on_grid(
            PointCloud {
                frame_id: "map".into(),
                points,
                grid: None,
                mesh_spacing_m: None,
            },
            grid,
        )
        .unwrap();
        let lens = Intrinsics::pinhole(640, 480, 960.0);
        (faces, map, vec![lens])
    }

    /// Camera at (3.5 + 0.5, y, z) looking along -x.
    fn shot(id: u32, y: f64, z: f64, blur_px: Option<f64>) -> Shot {
        let m = nalgebra::Matrix3::from_columns(&[Vector3::y(), -Vector3::z(), -Vector3::x()]);
        Shot {
            id,
            camera: Isometry3::from_parts(
                Translation3::new(4.0, y, z),
                UnitQuaternion::from_matrix(&m),
            ),
            lens: 0,
            blur_px,
        }
    }

    #[test]
    fn a_blurred_frame_inspects_nothing_and_the_culled_search_matches_the_naive_one() {
        let (faces, map, lenses) = scene();
        let view = ViewModel::default();
        let need = vec![1; faces.len()];
        let target = faces
            .iter()
            .position(|f| f.voxel == VoxelIndex([0, 4, 2]))
            .unwrap();
        let (y, z) = (faces[target].centre.y, faces[target].centre.z);
        // Blurred: 3.5 px streak over a 3 px limit.
        let blurred = cover(
            &faces,
            &need,
            &[shot(0, y, z, Some(3.5))],
            &lenses,
            &map,
            &view,
        );
        assert_eq!(blurred[target].views, 0);
        assert_eq!(blurred[target].miss, Some(Miss::Blurred));
        // Sharp, and blur unknown (not judged): both count.
        let shots = [
            shot(0, y, z, Some(3.5)),
            shot(1, y, z, Some(2.9)),
            shot(2, y, z + 0.1, None),
            shot(3, y + 20.0, z, Some(0.0)),
        ];
        let got = cover(&faces, &need, &shots, &lenses, &map, &view);
        assert_eq!(got[target].views, 2);
        assert_eq!(got[target].miss, None);
        assert_eq!(got[target].best.unwrap().1, 1);
        // A face 2 views are needed for, seen by 1, is short of views.
        let two = vec![2; faces.len()];
        let short = cover(&faces, &two, &shots[..2], &lenses, &map, &view);
        assert_eq!(short[target].miss, Some(Miss::TooFewViews));
        // The camera 20 m along the wall is too far for every face.
        let far = cover(&faces, &need, &shots[3..], &lenses, &map, &view);
        assert!(far.iter().all(|c| c.miss == Some(Miss::TooFar)));
        assert_eq!(
            got,
            cover_naive(&faces, &need, &shots, &lenses, &map, &view)
        );
    }
}
