//! One detection placed on the structure: rays from the camera through the
//! crack (its traced centre line, or the box when nothing could be traced)
//! onto the mapped surface, with the crack's extent and length measured on
//! that surface.

use std::borrow::Cow;
use std::collections::HashSet;

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use postflight_core::detection::{BoxXyxy, FrameDetection};
use postflight_core::map::{SlamMap, VoxelIndex};
use postflight_core::outputs::localise::{Outcome, WidthRecord};
use postflight_core::trace::Trace;
use postflight_core::view::Miss;
use postflight_core::{Intrinsics, ViewModel};

use crate::centre_line;
use crate::evidence::view_faults;

use crate::blur::Blur;
use crate::contrast::Contrast;
use crate::crossing::Crossing;
use crate::joint::Line;
use crate::surface::{self, SurfaceHit};
use crate::trace::CrackTrace;
use crate::view_width::{Footing, view_width};
use crate::width::widths;

/// A detection and where it lies on the structure.
#[derive(Debug, Clone)]
pub struct Observation {
    pub detection: FrameDetection,
    pub outcome: Outcome,
    /// Where the crack's centre line meets the surface (for a placed detection).
    pub placement: Option<Placement>,
    /// Centre-line pixels traced in the image (0: placed by its box).
    pub traced_px: u32,
    /// The box or the traced crack touches the image border: the crack may
    /// go on out of view.
    pub clipped: bool,
}

/// A detection's crack on the surface.
#[derive(Debug, Clone)]
pub struct Placement {
    /// The lines of sight through the detection's box.
    pub sight: Sight,
    /// The surface the crack lies on, hit at the crack's centre.
    pub hit: SurfaceHit,
    /// Centroid of the crack's centre line on the surface.
    pub centre: Point3<f64>,
    /// Corners of the axis-aligned box around the crack on the surface.
    pub extent: [Point3<f64>; 2],
    /// Farthest crack point from `centre`, metres.
    pub radius: f64,
    /// Length of the traced centre line on the surface, metres.
    pub length_m: Option<f64>,
    /// The traced centre line on the surface (empty where nothing was
    /// traced, or the view is too oblique to measure on).
    pub trace: Trace,
    /// Where its centre line runs out of the image, on the surface: the
    /// crack may go on there (empty when nothing was traced, or the view is
    /// too oblique to measure on).
    pub cut: Vec<Point3<f64>>,
    /// The straight line its centre line's pixels make on the surface's
    /// plane, from any angle (`None`: nothing traced); what tells a
    /// formwork joint.
    pub line: Option<Line>,
    /// Oblique ground sampling distance of the view, millimetres per pixel
    /// (see [`SurfaceHit::oblique_gsd_mm`]).
    pub oblique_gsd_mm: f64,
    /// The View model's GSD of the view (fronto-parallel at its range).
    pub view_gsd_mm: f64,
    /// The frame's motion blur, pixels (`None`: unknown).
    pub blur_px: Option<f64>,
    /// The View model's rules the view breaks.
    pub view_faults: Vec<Miss>,
    /// The crack's width on the surface as this view measures it (`None`:
    /// no centre line to measure across, or not yet measured).
    pub width: Option<WidthRecord>,
    /// The crack's crossings, where this view measures its width, waiting
    /// for the contrast their darkness divides by: the flight's cracks
    /// decide it ([`crate::contrast`]); then its `width`.
    pub crossed: Option<Crossed>,
    /// How far off the camera's position may be, metres (its frame's
    /// `position_std_m`: a photo's RTK accuracy).
    pub camera_std_m: Option<f64>,
}

/// A view's crossings of its crack, each with where it lies on the surface.
#[derive(Debug, Clone)]
pub struct Crossed {
    /// At each centre-line pixel of the trace (`None` where no profile fits).
    pub crossings: Vec<Option<Crossing>>,
    /// Each centre-line pixel's neighbours along the line.
    pub neighbours: Vec<Vec<usize>>,
    /// Where each crossing lies on the surface (`None` off it).
    pub footing: Vec<Option<Footing>>,
}

impl Crossed {
    /// The `crossings` of trace `t`, each with its footing on the surface
    /// (`on_plane`: an image pixel onto the surface's plane).
    fn on(
        t: &CrackTrace,
        crossings: Vec<Option<Crossing>>,
        on_plane: &impl Fn(Point2<f64>) -> Option<Point3<f64>>,
    ) -> Self {
        let footing = crossings
            .iter()
            .map(|c| {
                let c = c.as_ref()?;
                Some(Footing {
                    mm_per_px: surface_mm_per_px(c, on_plane)?,
                    at: on_plane(c.at)?,
                })
            })
            .collect();
        Crossed {
            footing,
            crossings,
            neighbours: crate::crossing::adjacency(t.pixels.len(), &t.edges),
        }
    }

    /// Its width, its darkness read over `contrast`, its walls as the
    /// camera's `blur` spreads them.
    pub fn width(&self, contrast: &Contrast, blur: &Blur) -> Option<WidthRecord> {
        let points = widths(&self.crossings, *contrast, blur);
        view_width(&points, &self.footing, &self.neighbours, contrast)
    }
}

/// What a detection is placed against.
pub struct Scene<'a> {
    pub map: &'a SlamMap,
    /// The structure's voxels (a plan's targets); `None`: every surface is.
    pub structure: Option<&'a HashSet<VoxelIndex>>,
    /// Rays end here, metres.
    pub max_range: f64,
    /// The rules each view is judged by.
    pub view: &'a ViewModel,
}

/// Pixels from the image border within which a box counts as clipped.
const BORDER_PX: f32 = 3.0;
/// Pixels from the image border within which a centre line's pixel is
/// where it runs out of view (thinning ends a line a few pixels short).
const CUT_PX: f32 = 6.0;
/// Views more oblique than this do not measure length, degrees from
/// face-on: ten past the View model's default largest incidence for an
/// inspection view, since a crack the plan sees only that steeply is better
/// measured than not (fine-GSD flights: median length error 8.8% to 9.6%
/// at 70 degrees, against 8.7% to 8.9% at 60; 11% at 75; docs/evaluation.md).
const MAX_MEASURED_INCIDENCE_DEG: f64 = 70.0;
/// Steepest view a width is measured from, degrees from face-on.
const MAX_WIDTH_INCIDENCE_DEG: f64 = 75.0;
/// The lines of sight through a detection's box: the camera centre and the
/// rays through the box's corners, in the world frame. The default holds
/// nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sight {
    pub origin: Point3<f64>,
    /// Rays through the box's corners, in order around it.
    pub corners: [Vector3<f64>; 4],
}

impl Sight {
    /// Whether `p` is in front of the camera within the box's lines of sight.
    pub fn holds(&self, p: &Point3<f64>) -> bool {
        let d = p - self.origin;
        let c = &self.corners;
        let sides: Vec<f64> = (0..4)
            .map(|i| c[i].cross(&c[(i + 1) % 4]).dot(&d))
            .collect();
        let axis: Vector3<f64> = c.iter().sum();
        axis.dot(&d) > 0.0 && (sides.iter().all(|s| *s >= 0.0) || sides.iter().all(|s| *s <= 0.0))
    }
}

/// Rays cast per detection, spread along the crack.
const RAYS: usize = 7;
/// Rays whose hit lies this far off the crack's surface met something else
/// (an edge, a background surface), metres.
const OFF_SURFACE: f64 = 0.25;

/// Whether a view at `incidence` (radians) measures length: at grazing
/// angles a pixel spans too much surface to measure on.
pub fn measures_length(incidence: f64) -> bool {
    incidence.to_degrees() <= MAX_MEASURED_INCIDENCE_DEG
}

impl Scene<'_> {
    /// Place a detection seen by a camera at `pose` (`T_world_camera`,
    /// optical frame) in a frame blurred by `blur_px` (`None`: unknown):
    /// its rays cast onto the map's surface, its pixels onto that surface's
    /// plane, then what the view measures there.
    pub fn place(
        &self,
        detection: FrameDetection,
        pose: &Isometry3<f64>,
        k: &Intrinsics,
        trace: Option<&CrackTrace>,
        crossings: Vec<Option<Crossing>>,
        blur_px: Option<f64>,
    ) -> Observation {
        let b = detection.detection.bbox;
        let mut observation = Observation {
            detection,
            outcome: Outcome::NoSurface,
            placement: None,
            traced_px: trace.map_or(0, |t| t.pixels.len() as u32),
            clipped: clipped(&b, trace, k),
        };
        let pixels = crack_pixels(&b, trace);
        let eye = Eye { pose, k };
        let Some(surface) = self.surface(&eye, &pixels) else {
            return observation;
        };
        // Every crack pixel onto the surface's plane.
        let on_surface: Vec<Option<Point3<f64>>> = pixels
            .iter()
            .map(|px| {
                eye.on_plane(px, &surface)
                    .filter(|p| (p - eye.origin()).norm() <= self.max_range)
            })
            .collect();
        let Some(footprint) = Footprint::of(&on_surface) else {
            return observation;
        };
        // Length and trace only from a view that measures; width from
        // steeper views too, each point's footprint across the crack taking
        // the slant (a crack seen only obliquely still gets a state). A
        // blurred frame measures neither: the smear stretches the crack's
        // line along the motion and widens or fades it across.
        let sharp = self.view.blur_miss(blur_px).is_none();
        let measured = trace.filter(|_| sharp && measures_length(surface.incidence));
        let length_m = measured.map(|t| {
            let at: Vec<Option<Vector3<f64>>> =
                on_surface.iter().map(|p| p.map(|p| p.coords)).collect();
            t.length(&at)
        });
        let on_plane = |px: Point2<f64>| eye.on_plane(&px, &surface);
        let line = trace.and_then(|t| {
            let points: Vec<Point3<f64>> = t.pixels.iter().filter_map(|p| on_plane(*p)).collect();
            Line::fit(&points)
        });
        let measures_width = sharp
            && surface.incidence.to_degrees() <= MAX_WIDTH_INCIDENCE_DEG
            && !crossings.is_empty();
        let crossed = trace
            .filter(|_| measures_width)
            .map(|t| Crossed::on(t, crossings, &on_plane));
        // The hit at the crack's centre, for its voxel, face, range and angle.
        let hit = SurfaceHit::new(self.map, &eye.origin(), footprint.centre, surface.normal);
        observation.outcome = match self.structure {
            Some(structure) if !near_structure(structure, hit.voxel) => Outcome::Obstacle,
            _ => Outcome::Placed,
        };
        let view_gsd_mm = ViewModel::gsd_mm(hit.range, k);
        let oblique_gsd_mm = hit.oblique_gsd_mm(k.fx.min(k.fy));
        // Within a pixel's footprint: the pixel grid's staircase goes.
        let trace = measured.map_or_else(Trace::default, |t| {
            centre_line::on_surface(t, &on_surface, oblique_gsd_mm / 1000.0)
        });
        let cut = measured.map_or_else(Vec::new, |t| cut_ends(t, &on_surface, k));
        observation.placement = Some(Placement {
            sight: eye.sight(&b),
            oblique_gsd_mm,
            view_gsd_mm,
            blur_px,
            view_faults: view_faults(
                self.view,
                hit.range,
                hit.incidence.to_degrees(),
                view_gsd_mm,
                blur_px,
            ),
            hit,
            centre: footprint.centre,
            extent: footprint.extent,
            radius: footprint.radius,
            length_m,
            trace,
            cut,
            line,
            width: None,
            crossed,
            camera_std_m: None,
        });
        observation
    }

    /// The surface the crack's rays agree on, if any: [`RAYS`] of them,
    /// spread along its pixels.
    fn surface(&self, eye: &Eye, pixels: &[Point2<f64>]) -> Option<SurfaceHit> {
        let hits: Vec<SurfaceHit> = spread(pixels, RAYS)
            .iter()
            .filter_map(|px| surface::cast(self.map, &eye.origin(), &eye.ray(px), self.max_range))
            .collect();
        consensus(&hits)
    }
}

/// A camera as a view casts from it: its pose and lens.
struct Eye<'a> {
    pose: &'a Isometry3<f64>,
    k: &'a Intrinsics,
}

impl Eye<'_> {
    fn origin(&self) -> Point3<f64> {
        Point3::from(self.pose.translation.vector)
    }

    /// The ray through pixel `px`, world frame.
    fn ray(&self, px: &Point2<f64>) -> Vector3<f64> {
        self.pose.rotation * self.k.ray(px)
    }

    /// Where pixel `px`'s ray meets the plane of `surface`.
    fn on_plane(&self, px: &Point2<f64>, surface: &SurfaceHit) -> Option<Point3<f64>> {
        intersect(
            &self.origin(),
            &self.ray(px),
            &surface.point,
            &surface.normal,
        )
    }

    /// The pyramid of rays through the box's corners.
    fn sight(&self, b: &BoxXyxy) -> Sight {
        Sight {
            origin: self.origin(),
            corners: [(b.x0, b.y0), (b.x1, b.y0), (b.x1, b.y1), (b.x0, b.y1)]
                .map(|(x, y)| self.ray(&Point2::new(f64::from(x), f64::from(y)))),
        }
    }
}

/// Whether the image border may cut the crack: its box, or its trace,
/// which follows it past the box, runs to the border.
fn clipped(b: &BoxXyxy, trace: Option<&CrackTrace>, k: &Intrinsics) -> bool {
    let at_border = |x: f32, y: f32| near_border(x, y, BORDER_PX, k);
    at_border(b.x0, b.y0)
        || at_border(b.x1, b.y1)
        || trace.is_some_and(|t| t.pixels.iter().any(|p| at_border(p.x as f32, p.y as f32)))
}

/// Whether `(x, y)` is within `margin` pixels of the image's border.
fn near_border(x: f32, y: f32, margin: f32, k: &Intrinsics) -> bool {
    let (w, h) = (k.width as f32, k.height as f32);
    x <= margin || y <= margin || x >= w - margin || y >= h - margin
}

/// The crack's pixels: its centre line, or the box's centre and diagonals.
fn crack_pixels<'a>(b: &BoxXyxy, trace: Option<&'a CrackTrace>) -> Cow<'a, [Point2<f64>]> {
    match trace {
        Some(t) => Cow::Borrowed(&t.pixels),
        None => {
            let (x0, y0, x1, y1) = (
                f64::from(b.x0),
                f64::from(b.y0),
                f64::from(b.x1),
                f64::from(b.y1),
            );
            [0.0, 0.25, 0.5, 0.75, 1.0]
                .iter()
                .flat_map(|s| {
                    [
                        Point2::new(x0 + (x1 - x0) * s, y0 + (y1 - y0) * s),
                        Point2::new(x1 - (x1 - x0) * s, y0 + (y1 - y0) * s),
                    ]
                })
                .collect()
        }
    }
}

/// Where a view puts a crack on the surface: the centre of its points,
/// the farthest of them from it, and their bounds.
struct Footprint {
    centre: Point3<f64>,
    radius: f64,
    extent: [Point3<f64>; 2],
}

impl Footprint {
    /// `None` where no pixel met the surface's plane.
    fn of(on_surface: &[Option<Point3<f64>>]) -> Option<Self> {
        let points: Vec<Point3<f64>> = on_surface.iter().flatten().copied().collect();
        let first = *points.first()?;
        let centre = Point3::from(
            points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64,
        );
        Some(Self {
            centre,
            radius: points
                .iter()
                .map(|p| (p - centre).norm())
                .fold(0.0, f64::max),
            extent: points
                .iter()
                .fold([first, first], |[lo, hi], p| [lo.inf(p), hi.sup(p)]),
        })
    }
}

/// The trace's points near the image border, on the surface: where the
/// border may cut the crack.
fn cut_ends(
    t: &CrackTrace,
    on_surface: &[Option<Point3<f64>>],
    k: &Intrinsics,
) -> Vec<Point3<f64>> {
    (t.pixels.iter().zip(on_surface))
        .filter(|(px, _)| near_border(px.x as f32, px.y as f32, CUT_PX, k))
        .filter_map(|(_, p)| *p)
        .collect()
}

/// Millimetres on the surface per image pixel across the crack at `p`:
/// a pixel's step across the line, on the surface, less its part along
/// the crack there (an oblique view slants the image's normal).
fn surface_mm_per_px(
    p: &Crossing,
    on_plane: &impl Fn(Point2<f64>) -> Option<Point3<f64>>,
) -> Option<f64> {
    let along = nalgebra::Vector2::new(p.across.y, -p.across.x);
    let across = on_plane(p.at + p.across * 0.5)? - on_plane(p.at - p.across * 0.5)?;
    let along =
        (on_plane(p.at + along * 0.5)? - on_plane(p.at - along * 0.5)?).try_normalize(1e-12)?;
    Some((across - along * across.dot(&along)).norm() * 1000.0)
}

/// A voxel of the structure, or touching one: map noise and a surface on a
/// voxel boundary put a hit one voxel off.
fn near_structure(structure: &HashSet<VoxelIndex>, v: VoxelIndex) -> bool {
    structure.contains(&v) || v.neighbours().any(|n| structure.contains(&n))
}

/// Up to `n` pixels spread along a pixel set: its extremes along its main
/// direction and evenly between.
fn spread(pixels: &[Point2<f64>], n: usize) -> Vec<Point2<f64>> {
    if pixels.len() <= n {
        return pixels.to_vec();
    }
    let count = pixels.len() as f64;
    let mean = pixels
        .iter()
        .map(|p| p.coords)
        .sum::<nalgebra::Vector2<f64>>()
        / count;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pixels {
        let d = p.coords - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let axis = nalgebra::Vector2::new(angle.cos(), angle.sin());
    let mut order: Vec<(f64, usize)> = pixels
        .iter()
        .enumerate()
        .map(|(i, p)| ((p.coords - mean).dot(&axis), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    (0..n)
        .map(|k| pixels[order[k * (order.len() - 1) / (n - 1)].1])
        .collect()
}

/// The surface most rays agree on: the hit at the median range, provided
/// the hits on its plane are at least half of all hits.
fn consensus(hits: &[SurfaceHit]) -> Option<SurfaceHit> {
    let mut by_range: Vec<&SurfaceHit> = hits.iter().collect();
    by_range.sort_by(|a, b| a.range.total_cmp(&b.range));
    let median = **by_range.get(by_range.len() / 2)?;
    let agree = hits
        .iter()
        .filter(|h| (h.point - median.point).dot(&median.normal).abs() < OFF_SURFACE)
        .count();
    (2 * agree >= hits.len()).then_some(median)
}

/// Where the ray from `origin` along `dir` meets the plane through `p` with normal `n`.
fn intersect(
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    p: &Point3<f64>,
    n: &Vector3<f64>,
) -> Option<Point3<f64>> {
    let denom = dir.dot(n);
    if denom.abs() < 1e-6 {
        return None;
    }
    let t = (p - origin).dot(n) / denom;
    (t > 0.0).then(|| origin + dir * t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::tests::wall;
    use nalgebra::{Translation3, UnitQuaternion};
    use postflight_core::Distortion;
    use postflight_core::defect_kind::DefectKind;
    use postflight_core::detection::{BoxXyxy, Detection};

    fn detection(bbox: [f32; 4]) -> FrameDetection {
        FrameDetection {
            frame: 0,
            time_ns: 0,
            detection: Detection {
                bbox: BoxXyxy {
                    x0: bbox[0],
                    y0: bbox[1],
                    x1: bbox[2],
                    y1: bbox[3],
                },
                score: 0.8,
                class: 0,
                kind: DefectKind::Crack,
                tile: -1,
                mask: None,
            },
        }
    }

    /// A strongly distorted camera, mounted on a body with a lever arm and
    /// a pitch (not an identity extrinsic), looking at the wall x = 3.
    fn camera() -> (Isometry3<f64>, Intrinsics) {
        let body = Isometry3::from_parts(
            Translation3::new(0.0, 0.2, 2.5),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.15),
        );
        let body_camera = Isometry3::from_parts(
            Translation3::new(0.25, 0.0, -0.12),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.2),
        ) * Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, 0.5, -0.5)),
        );
        let k = Intrinsics {
            width: 640,
            height: 480,
            fx: 600.0,
            fy: 600.0,
            cx: 320.0,
            cy: 240.0,
            distortion: Distortion::PlumbBob([-0.25, 0.08, 0.001, -0.001, 0.0]),
        };
        (body * body_camera, k)
    }

    /// A crack on the wall from `a` to `b`, as the camera images it: its
    /// pixels (through the lens distortion) and their spanning chain.
    fn imaged_crack(
        pose: &Isometry3<f64>,
        k: &Intrinsics,
        a: Point3<f64>,
        b: Point3<f64>,
    ) -> CrackTrace {
        let pixels: Vec<Point2<f64>> = (0..=100)
            .map(|i| {
                let p = a + (b - a) * (f64::from(i) / 100.0);
                k.project(&(pose.inverse() * p).coords).unwrap()
            })
            .collect();
        let edges = (0..100).map(|i| (i, i + 1)).collect();
        CrackTrace {
            pixels,
            edges,
            bridges: Vec::new(),
        }
    }

    fn bounds(t: &CrackTrace) -> [f32; 4] {
        t.pixels
            .iter()
            .fold([f32::MAX, f32::MAX, f32::MIN, f32::MIN], |b, p| {
                [
                    b[0].min(p.x as f32),
                    b[1].min(p.y as f32),
                    b[2].max(p.x as f32),
                    b[3].max(p.y as f32),
                ]
            })
    }

    #[test]
    fn a_crack_seen_through_a_distorted_lens_and_a_mounted_camera_lands_where_it_is() {
        let map = wall();
        let scene = Scene {
            map: &map,
            structure: None,
            max_range: 30.0,
            view: &ViewModel::default(),
        };
        let (pose, k) = camera();
        // A diagonal crack near the image corner, where distortion is strongest.
        let (a, b) = (Point3::new(3.0, 1.5, 2.2), Point3::new(3.0, 1.9, 2.7));
        let t = imaged_crack(&pose, &k, a, b);
        let corner = bounds(&t);
        assert!(
            corner[0] < 120.0 && corner[1] < 120.0,
            "crack not in a corner: {corner:?}"
        );
        let o = scene.place(detection(corner), &pose, &k, Some(&t), Vec::new(), None);
        assert_eq!(o.outcome, Outcome::Placed);
        let p = o.placement.unwrap();
        let mid = Point3::from((a.coords + b.coords) / 2.0);
        assert!((p.centre - mid).norm() < 0.02, "{:?} vs {mid:?}", p.centre);
        // The synthetic trace is continuous, not pixel steps: no chain bias to undo.
        let length = (b - a).norm();
        let measured = p.length_m.unwrap() / crate::trace::CHAIN_CORRECTION;
        assert!((measured - length).abs() / length < 0.03);
        assert!((p.radius - length / 2.0).abs() < 0.02);
        assert_eq!(p.hit.face(), "-x");
        // Ignoring the distortion would put it centimetres off: the test can fail.
        let pinhole = Intrinsics {
            distortion: Distortion::None,
            ..k.clone()
        };
        let wrong = scene.place(
            detection(corner),
            &pose,
            &pinhole,
            Some(&t),
            Vec::new(),
            None,
        );
        assert!((wrong.placement.unwrap().centre - mid).norm() > 0.05);
        // So would ignoring the mounting.
        let body_only = pose * Isometry3::translation(0.0, 0.12, -0.25);
        let wrong = scene.place(
            detection(corner),
            &body_only,
            &k,
            Some(&t),
            Vec::new(),
            None,
        );
        assert!((wrong.placement.unwrap().centre - mid).norm() > 0.1);
    }

    #[test]
    fn detections_that_meet_no_structure_say_why() {
        let map = wall();
        let (pose, k) = camera();
        let t = imaged_crack(
            &pose,
            &k,
            Point3::new(3.0, 0.2, 2.4),
            Point3::new(3.0, 0.4, 2.6),
        );
        let b = bounds(&t);
        // Out of range.
        let near = Scene {
            map: &map,
            structure: None,
            max_range: 1.0,
            view: &ViewModel::default(),
        };
        assert_eq!(
            near.place(detection(b), &pose, &k, Some(&t), Vec::new(), None)
                .outcome,
            Outcome::NoSurface
        );
        // On a surface that is not the structure.
        let elsewhere: HashSet<VoxelIndex> = [VoxelIndex([40, 40, 40])].into();
        let scene = Scene {
            map: &map,
            structure: Some(&elsewhere),
            max_range: 30.0,
            view: &ViewModel::default(),
        };
        assert_eq!(
            scene
                .place(detection(b), &pose, &k, Some(&t), Vec::new(), None)
                .outcome,
            Outcome::Obstacle
        );
        // Without a trace the box's centre and diagonals place it.
        let o = scene.place(detection(b), &pose, &k, None, Vec::new(), None);
        assert_eq!(o.traced_px, 0);
        assert!(o.placement.unwrap().length_m.is_none());
    }

    #[test]
    fn a_blurred_frame_places_the_crack_but_measures_neither_length_nor_width() {
        let map = wall();
        let view = ViewModel::default();
        let scene = Scene {
            map: &map,
            structure: None,
            max_range: 30.0,
            view: &view,
        };
        let (pose, k) = camera();
        let (a, b) = (Point3::new(3.0, 0.2, 2.4), Point3::new(3.0, 0.5, 2.7));
        let t = imaged_crack(&pose, &k, a, b);
        // A crack 3 px wide, flat-bottomed and 60 grey levels deep.
        let crossings: Vec<Option<Crossing>> = t
            .pixels
            .iter()
            .map(|p| {
                Some(Crossing {
                    at: *p,
                    across: nalgebra::Vector2::new(1.0, 0.0),
                    surface: 150.0,
                    noise: 2.0,
                    depth: 120.0,
                    darkness: 360.0,
                    noise_limit: 10.0,
                    walls: Some(crate::crossing::Walls {
                        half: 3.0,
                        quarter: 3.2,
                        three_quarters: 2.8,
                        rise: 0.8,
                    }),
                    half: Some(3.0),
                    sure: true,
                    flat: true,
                })
            })
            .collect();
        let place = |blur| {
            let o = scene.place(
                detection(bounds(&t)),
                &pose,
                &k,
                Some(&t),
                crossings.clone(),
                blur,
            );
            assert_eq!(o.outcome, Outcome::Placed);
            let mut p = o.placement.unwrap();
            p.width = p
                .crossed
                .take()
                .and_then(|c| c.width(&Contrast::given(0.85), &Blur::UNKNOWN));
            p
        };
        for sharp in [None, Some(0.5 * view.max_blur_px)] {
            let p = place(sharp);
            assert!(p.length_m.is_some() && p.width.is_some() && !p.trace.is_empty());
        }
        let p = place(Some(2.0 * view.max_blur_px));
        assert!(p.view_faults.contains(&Miss::Blurred));
        assert!((p.centre - Point3::from((a.coords + b.coords) / 2.0)).norm() < 0.02);
        assert!(p.length_m.is_none() && p.width.is_none() && p.trace.is_empty());
    }
}
