//! Orthographic pictures of the structure: its target voxels seen from
//! above, below and the sides, coloured by coverage status, with the defect
//! candidates and the follow-up flight drawn over them.

use std::collections::HashMap;

use crate::results::{TargetVoxel, VoxelStatus};
use crate::svg::Svg;

/// A direction the structure is looked at from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Top,
    Bottom,
    /// From -y, looking along +y.
    South,
    /// From +y, looking along -y.
    North,
}

impl Side {
    pub const ALL: [Self; 4] = [Self::Top, Self::South, Self::North, Self::Bottom];

    pub fn title(self) -> &'static str {
        match self {
            Self::Top => "from above",
            Self::Bottom => "from below",
            Self::South => "from the south (-y)",
            Self::North => "from the north (+y)",
        }
    }

    /// Plane coordinates `(u, v)` of a world point (v up in the picture)
    /// and its depth (larger is nearer the viewer).
    pub fn project(self, p: [f64; 3]) -> (f64, f64, f64) {
        let [x, y, z] = p;
        match self {
            Self::Top => (x, y, z),
            Self::Bottom => (x, -y, -z),
            Self::South => (x, z, -y),
            Self::North => (-x, z, y),
        }
    }
}

pub fn colour(status: VoxelStatus) -> &'static str {
    match status {
        VoxelStatus::Inspected => "#2e9e5b",
        VoxelStatus::PlannedMissed => "#d7301f",
        VoxelStatus::NotPlanned => "#f59e0b",
        VoxelStatus::Uninspectable => "#7c6f9f",
    }
}

/// What to draw over the voxels.
#[derive(Default)]
pub struct Overlay<'a> {
    /// Numbered markers (defect candidates in review order).
    pub markers: Vec<(String, [f64; 3])>,
    /// Polylines (the follow-up flight's sorties).
    pub paths: Vec<&'a [[f64; 3]]>,
    /// Waypoints and home.
    pub points: Vec<[f64; 3]>,
    pub home: Option<[f64; 3]>,
    /// Draw every voxel grey instead of by status.
    pub grey: bool,
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
    for i in nearest_per_cell(voxels, resolution, side) {
        let v = &voxels[i];
        let (u, w, _) = side.project(v.centre);
        let fill = if overlay.grey {
            "#b8bcc4"
        } else {
            colour(v.status)
        };
        svg.square(u, w, resolution * 0.96, fill);
    }
    for path in &overlay.paths {
        let points: Vec<(f64, f64)> = path
            .iter()
            .map(|p| {
                let (u, w, _) = side.project(*p);
                (u, w)
            })
            .collect();
        svg.polyline(&points, "#1f4fd1", 1.5);
    }
    for p in &overlay.points {
        let (u, w, _) = side.project(*p);
        svg.circle(u, w, 1.8, "#1f4fd1", "none");
    }
    if let Some(h) = overlay.home {
        let (u, w, _) = side.project(h);
        svg.circle(u, w, 5.0, "#ffffff", "#1f4fd1");
        svg.label(u, w, 7.0, 4.0, "home");
    }
    for (label, p) in &overlay.markers {
        let (u, w, _) = side.project(*p);
        svg.circle(u, w, 6.0, "#111827", "#ffffff");
        svg.label(u, w, 8.0, -6.0, label);
    }
    let metres = nice_length((bounds[1][0] - bounds[0][0]) / 5.0);
    svg.scale_bar(metres);
    svg.finish(side.title())
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
