//! The best views of each patch of the surface, for detect: every exposed
//! face of the structure's voxels (a plan's targets; else the map's)
//! against the frames near it, ranked by the View
//! model's own measure, and the best `views_per_patch` of them kept with
//! the face's box in their image ([`BestViews`]).
//!
//! A view of a face is a frame that has the face in its image, turned
//! towards it, not hidden behind the map. Views that keep the View model's
//! rules a view of a crack is measured by (largest incidence, distance
//! band, GSD, blur; not the viewing cone, which is coverage's, not
//! measurement's) rank first, then the finest: the surface's millimetres
//! per pixel, stretched by the incidence and smeared by the blur. A face
//! seen only against the rules (a deck's top, grazing from a fixed camera)
//! keeps its best views all the same, and twice as many: each such view is
//! a poor chance of finding a crack there, and the surveys measured in
//! BENCHMARKS.md lose cracks with fewer. Faces no frame sees in its image
//! are left to nobody.

use std::collections::{BTreeMap, HashSet};

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Point3, Vector3};
use postflight_core::best_views::{BestViews, FrameViews};
use postflight_core::detection::BoxXyxy;
use postflight_core::map::{FaceSide, SlamMap, VoxelIndex};
use postflight_core::{Flight, Intrinsics, ViewModel};
use rayon::prelude::*;

use crate::cover::Shot;
use crate::error::CoverageError;
use crate::face::{Face, exposed_faces};
use crate::shots::{flight_shots, lenses};
use crate::view::occluded;

/// How many times `views_per_patch` a face keeps when none of its views
/// keeps the View model's rules.
const POOR_VIEWS_FACTOR: usize = 2;

/// What the best views are chosen with.
#[derive(Debug, Clone, Copy)]
pub struct Choosing {
    /// Views kept for each patch (at least 1).
    pub views_per_patch: u32,
    /// Frames further from a face than this are not its views, metres
    /// (localise places nothing further).
    pub reach_m: f64,
    /// Exposure of frames that recorded none, seconds (for their blur).
    pub exposure_s: Option<f64>,
}

/// The best views among the flight's frames of every patch of the
/// `target` voxels (the structure, on the map's grid) or, without them,
/// of `map`.
pub fn best_views(
    flight: &Flight,
    map: &SlamMap,
    target: Option<&[VoxelIndex]>,
    view: &ViewModel,
    choosing: Choosing,
) -> Result<BestViews, CoverageError> {
    let lenses = lenses(flight)?;
    let shots = flight_shots(flight, &lenses, map, choosing.exposure_s).shots;
    let grid = map.voxels.grid;
    let mut faces: Vec<Face> = match target {
        Some(voxels) => {
            let solid: HashSet<VoxelIndex> = voxels.iter().copied().collect();
            exposed_faces(&grid, voxels, &solid)
        }
        None => map
            .voxels
            .voxels()
            .flat_map(|v| {
                map.voxels
                    .exposed_faces(v)
                    .map(move |side| Face::new(&grid, v, side))
            })
            .collect(),
    };
    // The map's voxels come in hash order: the same faces in the same order
    // every run, so ties go the same way.
    faces.sort_by_key(|f| (f.voxel, f.side));
    let coords: Vec<[f64; 3]> = shots
        .iter()
        .map(|s| s.camera.translation.vector.into())
        .collect();
    let tree = ImmutableKdTree::<f64, 3>::new_from_slice(&coords);
    let r2 = choosing.reach_m * choosing.reach_m;
    let judged: Vec<FaceViews> = faces
        .par_iter()
        .map(|face| {
            let mut near: Vec<usize> = Vec::new();
            if let Ok(tree) = &tree {
                let c = face.centre;
                tree.query(&[c.x, c.y, c.z])
                    .within::<SquaredEuclidean<f64>>(r2)
                    .unsorted()
                    .visit(|hit| near.push(hit.item as usize));
            }
            near.sort_unstable();
            face_views(face, &near, &shots, &lenses, map, view, choosing)
        })
        .collect();

    let mut frames: BTreeMap<u32, FrameViews> = shots
        .iter()
        .map(|s| (s.id, FrameViews::default()))
        .collect();
    let sizes: BTreeMap<u32, (u32, u32)> = flight
        .frames
        .iter()
        .filter_map(|f| Some((f.index, (f.width?, f.height?))))
        .collect();
    let mut patches_seen = 0;
    for face in &judged {
        patches_seen += u64::from(!face.seen_by.is_empty());
        for &shot in &face.seen_by {
            frames.entry(shots[shot].id).or_default().patches_seen += 1;
        }
        for (shot, bbox) in &face.best {
            let frame = shots[*shot].id;
            let scaled = in_frame_pixels(sizes.get(&frame), &lenses[shots[*shot].lens], bbox);
            frames.entry(frame).or_default().best.push(scaled);
        }
    }
    Ok(BestViews {
        views_per_patch: choosing.views_per_patch,
        patches: faces.len() as u64,
        patches_seen,
        frames,
    })
}

/// One face's views: the shots that have it in their image facing them,
/// and the best of those not hidden, with its box in their image.
struct FaceViews {
    seen_by: Vec<usize>,
    best: Vec<(usize, BoxXyxy)>,
}

/// How good a view is: the View model's rules it breaks first, then its
/// footprint (lower is better).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
struct Rank {
    rules_broken: u8,
    footprint_mm: f64,
}

/// Rank `face`'s views among the `near` shots and keep the best unhidden.
fn face_views(
    face: &Face,
    near: &[usize],
    shots: &[Shot],
    lenses: &[Intrinsics],
    map: &SlamMap,
    view: &ViewModel,
    choosing: Choosing,
) -> FaceViews {
    let size = map.voxels.grid.resolution;
    let mut ranked: Vec<(Rank, BoxXyxy, usize)> = near
        .iter()
        .filter_map(|&i| {
            rank(face, &shots[i], &lenses[shots[i].lens], view, size).map(|(r, b)| (r, b, i))
        })
        .collect();
    ranked.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
    let mut keep = choosing.views_per_patch as usize;
    if ranked.first().is_some_and(|(r, _, _)| r.rules_broken > 0) {
        keep *= POOR_VIEWS_FACTOR;
    }
    let mut best = Vec::new();
    for &(_, bbox, i) in &ranked {
        if best.len() >= keep {
            break;
        }
        let shot = &shots[i];
        if !occluded(map, &Point3::from(shot.camera.translation.vector), face) {
            best.push((i, bbox));
        }
    }
    FaceViews {
        seen_by: ranked.into_iter().map(|(_, _, i)| i).collect(),
        best,
    }
}

/// How well `shot` sees `face` (`size` metres across), and the face's box
/// in its image; `None` when it does not: none of the face in its image
/// (a close-up photo may show only the middle of a face, its centre
/// outside), or facing away.
fn rank(
    face: &Face,
    shot: &Shot,
    lens: &Intrinsics,
    view: &ViewModel,
    size: f64,
) -> Option<(Rank, BoxXyxy)> {
    let origin = Point3::from(shot.camera.translation.vector);
    let to_face = face.centre - origin;
    let distance_m = to_face.norm();
    if distance_m < 1e-9 {
        return None;
    }
    let bbox = image_box(face, shot, lens, size).filter(|b| b.x1 > b.x0 && b.y1 > b.y0)?;
    let incidence_deg = face
        .normal
        .dot(&(-to_face / distance_m))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    // Facing away: the face cannot be in the picture. Grazing views rank
    // after the rest, but a face seen only so (a deck's top from a fixed
    // camera) keeps them: cracks show there too.
    if incidence_deg >= 89.0 {
        return None;
    }
    let gsd_mm = ViewModel::gsd_mm(distance_m, lens);
    let rules_broken = [
        view.incidence_miss(incidence_deg),
        view.distance_miss(distance_m),
        view.gsd_miss(gsd_mm),
        view.blur_miss(shot.blur_px),
    ]
    .iter()
    .filter(|m| m.is_some())
    .count() as u8;
    let smear = shot
        .blur_px
        .filter(|b| b.is_finite())
        .unwrap_or(0.0)
        .max(1.0);
    let rank = Rank {
        rules_broken,
        footprint_mm: gsd_mm / incidence_deg.to_radians().cos().max(1e-3) * smear,
    };
    Some((rank, bbox))
}

/// The box in `shot`'s image (its lens's pixels) of the square `face`
/// `size` metres across, clipped to the image; `None` when none of it is
/// in front of the camera.
fn image_box(face: &Face, shot: &Shot, lens: &Intrinsics, size: f64) -> Option<BoxXyxy> {
    let (u, v) = tangents(face.side);
    let half = size / 2.0;
    let to_camera = shot.camera.inverse();
    let pixels: Vec<_> = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
        .iter()
        .filter_map(|(a, b)| {
            let corner: Point3<f64> = face.centre + u * (a * half) + v * (b * half);
            lens.project(&(to_camera * corner).coords)
        })
        .collect();
    if pixels.is_empty() {
        return None;
    }
    let (w, h) = (f64::from(lens.width), f64::from(lens.height));
    let x0 = pixels.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
    let x1 = pixels.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
    let y0 = pixels.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let y1 = pixels.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
    Some(BoxXyxy {
        x0: x0.clamp(0.0, w) as f32,
        y0: y0.clamp(0.0, h) as f32,
        x1: x1.clamp(0.0, w) as f32,
        y1: y1.clamp(0.0, h) as f32,
    })
}

/// Two unit vectors along a face on `side`.
fn tangents(side: FaceSide) -> (Vector3<f64>, Vector3<f64>) {
    match side.axis() {
        0 => (Vector3::y(), Vector3::z()),
        1 => (Vector3::x(), Vector3::z()),
        _ => (Vector3::x(), Vector3::y()),
    }
}

/// `bbox` in the lens's pixels as pixels of a frame `size` (width,
/// height) large, which may have been stored at another size than the
/// lens was calibrated at.
fn in_frame_pixels(size: Option<&(u32, u32)>, lens: &Intrinsics, bbox: &BoxXyxy) -> BoxXyxy {
    let Some(&(w, h)) = size.filter(|&&(w, h)| w > 0 && h > 0) else {
        return *bbox;
    };
    let (sx, sy) = (
        w as f32 / lens.width.max(1) as f32,
        h as f32 / lens.height.max(1) as f32,
    );
    BoxXyxy {
        x0: bbox.x0 * sx,
        y0: bbox.y0 * sy,
        x1: bbox.x1 * sx,
        y1: bbox.y1 * sy,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use postflight_core::map::VoxelIndex;

    use crate::cover::tests::scene;

    /// Camera at (x, y, 1.25) looking along -x.
    fn shot(id: u32, x: f64, y: f64) -> Shot {
        let m = nalgebra::Matrix3::from_columns(&[Vector3::y(), -Vector3::z(), -Vector3::x()]);
        Shot {
            id,
            camera: Isometry3::from_parts(
                Translation3::new(x, y, 1.25),
                UnitQuaternion::from_matrix(&m),
            ),
            lens: 0,
            blur_px: Some(0.0),
        }
    }

    #[test]
    fn the_nearest_straightest_views_win_and_a_blurred_one_loses() {
        // A wall in the plane x = 0.45, seen through a 640 x 480 lens.
        let (_, map, lenses) = scene();
        let face = Face::new(&map.voxels.grid, VoxelIndex([0, 4, 2]), FaceSide::PosX);
        let (y, view) = (face.centre.y, ViewModel::default());
        let mut blurred = shot(3, 3.0, y);
        blurred.blur_px = Some(5.0);
        let shots = [
            // Farther and off to the side.
            shot(0, 4.0, y + 0.6),
            // Straight in front, nearest.
            shot(1, 3.0, y),
            // As near, a little oblique.
            shot(2, 3.0, y + 0.4),
            // Straight in front, blurred past the limit.
            blurred,
            // The face is not in its image.
            shot(4, 3.0, y + 30.0),
        ];
        let choosing = Choosing {
            views_per_patch: 2,
            reach_m: 10.0,
            exposure_s: None,
        };
        let judge = |shots: &[Shot]| {
            face_views(
                &face,
                &[0, 1, 2, 3, 4],
                shots,
                &lenses,
                &map,
                &view,
                choosing,
            )
        };
        let got = judge(&shots);
        assert_eq!(got.best.iter().map(|b| b.0).collect::<Vec<_>>(), [1, 2]);
        assert_eq!(got.seen_by.len(), 4);
        // Straight ahead at 2.5 m: the face, 0.5 m across, is 192 px wide
        // about the image centre.
        let b = got.best[0].1;
        assert!(((b.x1 - b.x0) - 192.0).abs() < 1.0, "{b:?}");
        assert!(((b.x0 + b.x1) / 2.0 - 320.0).abs() < 1.0, "{b:?}");
        assert!(rank(&face, &shots[4], &lenses[0], &view, 0.5).is_none());
        // A close-up shows the middle of a face, its centre and corners
        // out of the picture: still a view, the whole image its box.
        let mut close = shot(5, 0.6, y);
        close.camera.translation.vector.z = face.centre.z + 0.2;
        let (_, b) = rank(&face, &close, &lenses[0], &view, 0.5).unwrap();
        assert_eq!((b.x0, b.y0, b.x1, b.y1), (0.0, 0.0, 640.0, 480.0));
        // Seen only against the rules (every view blurred): twice the views.
        let blurred: Vec<Shot> = shots
            .iter()
            .map(|s| Shot {
                blur_px: Some(5.0),
                ..s.clone()
            })
            .collect();
        let got = judge(&blurred);
        assert_eq!(
            got.best.iter().map(|b| b.0).collect::<Vec<_>>(),
            [1, 3, 2, 0]
        );
    }
}
