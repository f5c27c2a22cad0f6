//! Orthographic pictures of the structure: its target voxels seen from
//! above, below and the sides, coloured by coverage status, with the defect
//! candidates and the follow-up flight drawn over them.

use std::collections::HashMap;

use postflight_core::condition::ConditionState;
use postflight_core::trace::Trace;

use crate::results::{TargetVoxel, VoxelStatus};
use crate::svg::Svg;

/// A direction the structure is looked at from (map x east, y north).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Top,
    Bottom,
    /// From -y, looking north.
    South,
    /// From +y, looking south.
    North,
    /// From +x, looking west.
    East,
    /// From -x, looking east.
    West,
}

impl Side {
    pub const ALL: [Self; 6] = [
        Self::Top,
        Self::Bottom,
        Self::South,
        Self::North,
        Self::East,
        Self::West,
    ];

    pub fn title(self) -> &'static str {
        match self {
            Self::Top => "from above",
            Self::Bottom => "from below",
            Self::South => "from the south (-y)",
            Self::North => "from the north (+y)",
            Self::East => "from the east (+x)",
            Self::West => "from the west (-x)",
        }
    }

    /// Unit vector from the structure towards the viewer.
    pub fn toward_viewer(self) -> [f64; 3] {
        match self {
            Self::Top => [0.0, 0.0, 1.0],
            Self::Bottom => [0.0, 0.0, -1.0],
            Self::South => [0.0, -1.0, 0.0],
            Self::North => [0.0, 1.0, 0.0],
            Self::East => [1.0, 0.0, 0.0],
            Self::West => [-1.0, 0.0, 0.0],
        }
    }

    /// The side a surface facing `normal` is best seen from.
    pub fn facing(normal: [f64; 3]) -> Self {
        Self::ALL
            .into_iter()
            .max_by(|a, b| {
                dot(a.toward_viewer(), normal).total_cmp(&dot(b.toward_viewer(), normal))
            })
            .unwrap_or(Self::Top)
    }

    /// Plane coordinates `(u, v)` of a world point, as the viewer sees it
    /// (u to their right, v up in the picture), and its depth (larger is
    /// nearer the viewer).
    pub fn project(self, p: [f64; 3]) -> (f64, f64, f64) {
        let [x, y, z] = p;
        match self {
            Self::Top => (x, y, z),
            Self::Bottom => (x, -y, -z),
            Self::South => (x, z, -y),
            Self::North => (-x, z, y),
            Self::East => (y, z, x),
            Self::West => (-y, z, -x),
        }
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A marker for a spot on the surface: drawn only in views that see the
/// surface it is on.
#[derive(Debug, Clone)]
pub struct Marker<'a> {
    pub label: String,
    pub position: [f64; 3],
    /// Outward normal of the surface at the spot.
    pub normal: [f64; 3],
    /// The crack's trace there, drawn in its condition state's colour.
    pub trace: &'a Trace,
    pub condition: Option<ConditionState>,
}

/// A surface turned at least this much towards the viewer is drawn in its
/// view (cos 75 degrees).
const SEEN_COS: f64 = 0.26;

/// Follow-up waypoint colours by height, low to high (viridis).
pub const HEIGHT_COLOURS: [&str; 6] = [
    "#440154", "#414487", "#2a788e", "#22a884", "#7ad151", "#fde725",
];

pub fn colour(status: VoxelStatus) -> &'static str {
    match status {
        VoxelStatus::Inspected => "#2e9e5b",
        VoxelStatus::PlannedMissed => "#d7301f",
        VoxelStatus::NotPlanned => "#f59e0b",
        VoxelStatus::Uninspectable => "#7c6f9f",
    }
}

/// A crack's colour by its condition state (none: grey), in the
/// elevations and the recording.
pub fn state_colour(state: Option<ConditionState>) -> &'static str {
    match state {
        None => "#6b7280",
        Some(ConditionState::Good) => "#2e9e5b",
        Some(ConditionState::Fair) => "#f59e0b",
        Some(ConditionState::Poor) => "#d7301f",
        Some(ConditionState::Severe) => "#7c3aed",
    }
}

/// What to draw over the voxels.
#[derive(Default)]
pub struct Overlay<'a> {
    /// Numbered markers (defect candidates in review order).
    pub markers: Vec<Marker<'a>>,
    /// Polylines (the follow-up flight's sorties).
    pub paths: Vec<&'a [[f64; 3]]>,
    /// Waypoints in flight order, numbered and coloured by height.
    pub points: Vec<[f64; 3]>,
    pub home: Option<[f64; 3]>,
    /// Draw every voxel grey instead of by status.
    pub grey: bool,
}

/// How wide the voxels are seen from `side`, metres (to draw every side at
/// one scale).
pub fn width_m(voxels: &[TargetVoxel], resolution: f64, side: Side) -> f64 {
    let (lo, hi) = voxels
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            let u = side.project(v.centre).0;
            (lo.min(u), hi.max(u))
        });
    if lo.is_finite() {
        hi - lo + 2.0 * resolution
    } else {
        0.0
    }
}

/// One view of the voxels: per picture cell only the voxel nearest the
/// viewer is drawn, so a million voxels make at most a picture's worth of
/// squares, each an honest picture of what a camera there would see.
pub fn view(
    voxels: &[TargetVoxel],
    resolution: f64,
    side: Side,
    overlay: &Overlay,
    width: f64,
) -> String {
    let mut bounds = [[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]];
    let mut grow = |p: [f64; 3], pad: f64| {
        let (u, w, _) = side.project(p);
        bounds[0][0] = bounds[0][0].min(u - pad);
        bounds[0][1] = bounds[0][1].min(w - pad);
        bounds[1][0] = bounds[1][0].max(u + pad);
        bounds[1][1] = bounds[1][1].max(w + pad);
    };
    for v in voxels {
        grow(v.centre, resolution);
    }
    for p in overlay.paths.iter().flat_map(|p| p.iter()) {
        grow(*p, resolution);
    }
    if !bounds[0][0].is_finite() {
        return String::new();
    }
    let mut svg = Svg::new(bounds, width, 12.0);
    let drawn = nearest_per_cell(voxels, resolution, side);
    let cell = |c: f64| (c / resolution).floor() as i64;
    let mut front: HashMap<(i64, i64), f64> = HashMap::new();
    for &i in &drawn {
        let v = &voxels[i];
        let (u, w, depth) = side.project(v.centre);
        front.insert((cell(u), cell(w)), depth);
        let fill = if overlay.grey {
            "#b8bcc4"
        } else {
            colour(v.status)
        };
        svg.square(u, w, resolution * 0.96, fill);
    }
    for path in &overlay.paths {
        svg.polyline(&projected(side, path), "#1f4fd1", 1.5);
    }
    waypoints(&mut svg, side, &overlay.points);
    if let Some(h) = overlay.home {
        let (u, w, _) = side.project(h);
        svg.circle(u, w, 5.0, "#ffffff", "#1f4fd1");
        svg.take(u, w, 5.0);
        svg.label_clear(u, w, 7.0, "home", 11.0);
    }
    // A marker shows where its surface faces the viewer: solid where that
    // spot is in front, hollow where nearer parts hide it.
    let shown: Vec<(&Marker, bool)> = overlay
        .markers
        .iter()
        .filter(|m| dot(m.normal, side.toward_viewer()) >= SEEN_COS)
        .map(|m| {
            let (u, w, depth) = side.project(m.position);
            let front = front
                .get(&(cell(u), cell(w)))
                .is_none_or(|f| depth >= f - 1.5 * resolution);
            (m, front)
        })
        .collect();
    for (m, in_front) in &shown {
        let (u, w, _) = side.project(m.position);
        if *in_front {
            svg.circle(u, w, 6.0, "#111827", "#ffffff");
        } else {
            svg.circle(u, w, 5.0, "none", "#111827");
        }
        svg.take(u, w, 6.0);
    }
    // Over the markers: a crack shorter than a marker is still seen.
    for (m, _) in &shown {
        for line in &m.trace.0 {
            let points = projected(side, line);
            // A white halo: the state's colour may be a voxel status's too.
            svg.polyline(&points, "#ffffff", 5.0);
            svg.polyline(&points, state_colour(m.condition), 2.5);
        }
    }
    for (m, _) in &shown {
        let (u, w, _) = side.project(m.position);
        svg.label_clear(u, w, 8.0, &m.label, 11.0);
    }
    let metres = nice_length((bounds[1][0] - bounds[0][0]) / 5.0);
    svg.scale_bar(metres);
    svg.finish(side.title())
}

/// A polyline as seen from `side`, in the picture's plane.
fn projected(side: Side, line: &[[f64; 3]]) -> Vec<(f64, f64)> {
    line.iter()
        .map(|p| {
            let (u, w, _) = side.project(*p);
            (u, w)
        })
        .collect()
}

/// Waypoints coloured by height and numbered in flight order (a number
/// that would overlap another is left out), with the colour ramp.
fn waypoints(svg: &mut Svg, side: Side, points: &[[f64; 3]]) {
    if points.is_empty() {
        return;
    }
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    let colour_of = |z: f64| {
        let t = if hi > lo { (z - lo) / (hi - lo) } else { 0.5 };
        HEIGHT_COLOURS[((t * HEIGHT_COLOURS.len() as f64) as usize).min(HEIGHT_COLOURS.len() - 1)]
    };
    svg.ramp(
        &HEIGHT_COLOURS,
        &format!("{lo:.1} m"),
        &format!("{hi:.1} m"),
    );
    for p in points {
        let (u, w, _) = side.project(*p);
        svg.circle(u, w, 3.5, colour_of(p[2]), "#1f2937");
        svg.take(u, w, 3.5);
    }
    for (i, p) in points.iter().enumerate() {
        let (u, w, _) = side.project(*p);
        svg.label_clear(u, w, 4.0, &(i + 1).to_string(), 9.0);
    }
}

/// The voxels a view of `side` draws: per picture cell the one nearest the
/// viewer (indices into `voxels`), far to near so that nearer squares cover
/// farther ones' edges.
pub fn nearest_per_cell(voxels: &[TargetVoxel], resolution: f64, side: Side) -> Vec<usize> {
    let mut front: HashMap<(i64, i64), (f64, usize)> = HashMap::new();
    let cell = |c: f64| (c / resolution).floor() as i64;
    for (i, v) in voxels.iter().enumerate() {
        let (u, w, depth) = side.project(v.centre);
        let slot = front.entry((cell(u), cell(w))).or_insert((depth, i));
        if depth > slot.0 {
            *slot = (depth, i);
        }
    }
    let mut drawn: Vec<(f64, usize)> = front.into_values().collect();
    // Ties in voxel order, so the same run draws the same picture.
    drawn.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    drawn.into_iter().map(|(_, i)| i).collect()
}

/// 1, 2 or 5 times a power of ten, at most `x`.
fn nice_length(x: f64) -> f64 {
    if x <= 0.0 || !x.is_finite() {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * p)
        .find(|l| *l <= x)
        .unwrap_or(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn voxel(centre: [f64; 3], status: VoxelStatus) -> TargetVoxel {
        TargetVoxel {
            index: [0; 3],
            centre,
            status,
        }
    }

    #[test]
    fn the_voxel_nearest_the_viewer_is_drawn() {
        // A gap under an inspected voxel: hidden from above, seen from below.
        let voxels = [
            voxel([0.25, 0.25, 0.25], VoxelStatus::PlannedMissed),
            voxel([0.25, 0.25, 0.75], VoxelStatus::Inspected),
        ];
        let top = view(&voxels, 0.5, Side::Top, &Overlay::default(), 200.0);
        let bottom = view(&voxels, 0.5, Side::Bottom, &Overlay::default(), 200.0);
        let squares = |s: &str| s.matches("<rect").count();
        assert_eq!(squares(&top), 1);
        assert!(top.contains(colour(VoxelStatus::Inspected)));
        assert!(!top.contains(colour(VoxelStatus::PlannedMissed)));
        assert!(bottom.contains(colour(VoxelStatus::PlannedMissed)));
        let south = view(&voxels, 0.5, Side::South, &Overlay::default(), 200.0);
        assert_eq!(squares(&south), 2);
    }

    #[test]
    fn scale_bars_are_round() {
        assert_eq!(nice_length(7.3), 5.0);
        assert_eq!(nice_length(0.34), 0.2);
        assert_eq!(nice_length(19.0), 10.0);
    }
}
