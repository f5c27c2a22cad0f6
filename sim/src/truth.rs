//! Ground truth: what really is where, and what each frame really saw.

use nalgebra::{Isometry3, Point3};
use postflight_core::Intrinsics;
use postflight_core::map::{FaceSide, VoxelGrid, VoxelIndex};
use postflight_core::serde_pose::PoseJson;
use serde::Serialize;

use crate::crack::{Crack, Opening, WidthRange};
use crate::distractor::{Distractor, DistractorKind};
use crate::render;
use crate::scene::Scene;

/// Fraction of a pixel a crack must cover (after the motion blur or the lens
/// spreads it) to show as a dark line.
pub const MIN_CRACK_CONTRAST: f64 = 0.25;

#[derive(Debug, Clone, Serialize)]
pub struct CrackTruth {
    pub id: u32,
    /// Main line first, then branches; world coordinates, metres.
    pub lines: Vec<Vec<[f64; 3]>>,
    /// Its widest, millimetres.
    pub width_mm: f64,
    /// Width at each point of each line, millimetres (cracks that open and
    /// close along their length).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub widths_mm: Option<Vec<Vec<f64>>>,
    /// Median width along the crack's length, millimetres (tapered cracks).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub median_width_mm: Option<f64>,
    /// The condition state its widest point puts it in, by the default
    /// limits for reinforced concrete (tapered cracks).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub condition_state: Option<u8>,
    pub length_m: f64,
    /// The pattern it is one crack of (its number and the spacing its
    /// cracks were drawn at), if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pattern: Option<crate::crack::Pattern>,
    pub part: String,
    /// Outward normal of the surface.
    pub normal: [f64; 3],
    /// Voxel (plan grid) holding the crack's centroid, and the face it is on.
    pub voxel: VoxelIndex,
    pub face: FaceSide,
}

impl CrackTruth {
    pub fn new(crack: &Crack, scene: &Scene, grid: &VoxelGrid) -> Self {
        let n = crack.normal;
        // Just inside the surface, so the voxel is the structure's, not the air's.
        let inside = crack.centroid() - n * (grid.resolution * 1e-3);
        let tapered = matches!(crack.opening, Opening::Tapered { .. });
        Self {
            id: crack.id,
            lines: crack
                .lines
                .iter()
                .map(|l| l.iter().map(|p| [p.x, p.y, p.z]).collect())
                .collect(),
            width_mm: crack.width * 1000.0,
            widths_mm: tapered.then(|| {
                crack
                    .widths()
                    .iter()
                    .map(|l| l.iter().map(|w| w * 1000.0).collect())
                    .collect()
            }),
            median_width_mm: tapered.then(|| median_width(crack) * 1000.0),
            condition_state: tapered.then(|| {
                postflight_core::condition::CrackLimits::default()
                    .state(crack.width * 1000.0)
                    .number()
            }),
            length_m: crack.length(),
            pattern: crack.pattern,
            part: scene.part_name(crack.triangle).to_string(),
            normal: [n.x, n.y, n.z],
            voxel: grid.voxel_of(&inside),
            face: FaceSide::nearest(&n),
        }
    }
}

/// A mark on the surface that is not a crack.
#[derive(Debug, Clone, Serialize)]
pub struct DistractorTruth {
    pub kind: DistractorKind,
    /// See [`Distractor::line`]; world coordinates, metres.
    pub line: [[f64; 3]; 2],
    /// See [`Distractor::width`], millimetres.
    pub width_mm: f64,
    pub part: String,
    pub normal: [f64; 3],
}

impl DistractorTruth {
    pub fn new(mark: &Distractor, scene: &Scene) -> Self {
        let p = |p: &Point3<f64>| [p.x, p.y, p.z];
        Self {
            kind: mark.kind,
            line: [p(&mark.line[0]), p(&mark.line[1])],
            width_mm: mark.width * 1000.0,
            part: scene.part_name(mark.triangle).to_string(),
            normal: [mark.normal.x, mark.normal.y, mark.normal.z],
        }
    }
}

/// The median of a crack's width along its length (samples 1 mm apart).
fn median_width(crack: &Crack) -> f64 {
    let mut widths: Vec<f64> = crack.samples(0.001).iter().map(|s| s.1).collect();
    widths.sort_by(f64::total_cmp);
    widths.get(widths.len() / 2).copied().unwrap_or(crack.width)
}

/// A crack as one frame saw it.
#[derive(Debug, Clone, Serialize)]
pub struct CrackInFrame {
    pub id: u32,
    /// Visible crack points projected into the image, pixels.
    pub polyline_px: Vec<[f64; 2]>,
    /// `[x_min, y_min, x_max, y_max]` of the visible points, pixels.
    pub bbox: [f64; 4],
    /// Share of the crack's length in view, unoccluded and wide enough to show.
    pub visible_fraction: f64,
    /// Crack width over pixel footprint at the crack's centre (1 = fills a
    /// pixel), divided by how many pixels the blur streak or the lens
    /// spreads a thin line over, when that exceeds one ([`spread_px`]).
    pub contrast: f64,
    /// Its widest visible point's width across the crack, pixels (cracks
    /// that open and close along their length).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width_px: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct FrameTruth {
    /// Index among all simulated frames, dropped ones included.
    pub index: u32,
    pub time_ns: i64,
    /// Not written to the recording (a dropped frame).
    pub dropped: bool,
    /// True pose of the camera optical frame in the world.
    pub camera_pose: PoseJson,
    /// Taken on a rushed leg of the flight.
    pub fast: bool,
    /// Length of the motion blur streak, pixels.
    pub blur_px: f64,
    pub cracks: Vec<CrackInFrame>,
    /// The area defects it sees (their ids in `area_defects`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub area_defects: Vec<String>,
}

/// How many pixels a thin line's darkness is spread over: a blur streak's
/// length or the lens's spread ([`render::lens_spread_px`]), whichever is
/// more; the pixel grid alone spreads it over one pixel.
pub fn spread_px(blur_px: f64, lens_blur_px: f64) -> f64 {
    blur_px.max(render::lens_spread_px(lens_blur_px)).max(1.0)
}

/// Which cracks a camera sees and where, by projecting points 5 mm apart
/// along each crack and casting a ray to each.
pub fn cracks_in_view(
    scene: &Scene,
    cracks: &[Crack],
    k: &Intrinsics,
    camera: &Isometry3<f64>,
    blur_px: f64,
    lens_blur_px: f64,
) -> Vec<CrackInFrame> {
    let spread = spread_px(blur_px, lens_blur_px);
    let origin = Point3::from(camera.translation.vector);
    let world_to_camera = camera.inverse();
    let margin = 2.0;
    let mut seen = Vec::new();
    for crack in cracks {
        let to_camera = origin - crack.centroid();
        let range = to_camera.norm();
        if crack.normal.dot(&to_camera) <= 0.0 || range > 60.0 {
            continue;
        }
        let samples = crack.samples(0.005);
        let tapered = matches!(crack.opening, Opening::Tapered { .. });
        let mut visible = Vec::new();
        let mut widest_px: f64 = 0.0;
        for (p, width) in &samples {
            let Some(px) = k.project(&(world_to_camera * p).coords) else {
                continue;
            };
            if px.x < margin
                || px.y < margin
                || px.x > f64::from(k.width) - margin
                || px.y > f64::from(k.height) - margin
            {
                continue;
            }
            let d = origin - p;
            let dist = d.norm();
            let dir = -d / dist;
            let cos = crack.normal.dot(&(d / dist));
            if width / (dist / k.fx / cos.max(0.2)) / spread < MIN_CRACK_CONTRAST {
                continue;
            }
            let unblocked = scene
                .cast(&origin, &dir, dist + 0.05)
                .is_none_or(|h| h.distance > dist - 0.01);
            if unblocked {
                visible.push([px.x, px.y]);
                if tapered {
                    // Across the crack, where a pixel is stretched by the
                    // surface's slant in that direction only.
                    let across = crack.normal.cross(&crack.nearest(p).along);
                    let slant = (1.0 - across.dot(&dir).powi(2)).max(1e-6).sqrt();
                    widest_px = widest_px.max(width * slant * k.fx / dist);
                }
            }
        }
        // Any visible piece counts, however much of the crack is out of
        // frame or hidden: an inspector sees that piece.
        let fraction = visible.len() as f64 / samples.len().max(1) as f64;
        if visible.len() < 6 {
            continue;
        }
        let bbox = visible.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |b, p| {
                [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ]
            },
        );
        let cos = crack.normal.dot(&(to_camera / range)).max(0.2);
        seen.push(CrackInFrame {
            id: crack.id,
            polyline_px: visible,
            bbox,
            visible_fraction: fraction,
            contrast: crack.width / (range / k.fx / cos) / spread,
            width_px: tapered.then_some(widest_px),
        });
    }
    seen
}

#[derive(Debug, Clone, Serialize)]
pub struct Truth {
    pub scene: String,
    pub seed: u64,
    pub exposure_s: f64,
    pub camera: Intrinsics,
    /// `T_body_camera`: the camera optical frame in the body frame (with a
    /// gimbal, at the pitch the sides are shot at; each frame's
    /// `camera_pose` is exact).
    pub t_body_camera: PoseJson,
    /// The camera was on a gimbal, its pitch recorded on `/tf`.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub gimbal: bool,
    pub pose_noise: PoseNoise,
    pub skipped_viewpoints: Vec<usize>,
    /// The widths cracks open and close between, when they taper.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crack_widths: Option<WidthRange>,
    pub cracks: Vec<CrackTruth>,
    /// Marks on the surface that are not cracks.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub distractors: Vec<DistractorTruth>,
    /// Spalls and the bars showing in them (`--spalls`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub area_defects: Vec<crate::spall::AreaDefectTruth>,
    pub frames: Vec<FrameTruth>,
    /// Per-voxel coverage under the plan's View model, flown and planned.
    pub coverage: crate::coverage::CoverageTruth,
    /// A repeat flight's earlier flight, frame and changes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeat: Option<crate::repeat::RepeatTruth>,
    /// The recordings a flight cut into sorties was written as.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sorties: Option<Vec<crate::sortie::SortieTruth>>,
    /// Where the world frame is on the Earth and the GPS fixes' noise,
    /// when the flight records GPS.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gps: Option<crate::gps::GpsTruth>,
}

/// White noise added to each recorded pose, 1 sigma.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, clap::Args)]
pub struct PoseNoise {
    /// Position noise of the recorded poses, metres (1 sigma, per pose).
    #[arg(long = "pose-noise", default_value_t = crate::flight::POSITION_NOISE, value_name = "METRES")]
    pub position_m: f64,
    /// Yaw noise of the recorded poses, degrees (1 sigma, per pose).
    #[arg(
        long = "yaw-noise",
        default_value_t = crate::flight::YAW_NOISE.to_degrees(),
        value_name = "DEGREES",
        value_parser = radians,
    )]
    pub yaw_rad: f64,
}

/// An angle given in degrees, in radians.
fn radians(degrees: &str) -> Result<f64, String> {
    let degrees: f64 = degrees.parse().map_err(|e| format!("{e}"))?;
    Ok(degrees.to_radians())
}
