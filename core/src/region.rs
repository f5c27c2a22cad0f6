//! Regions of the map frame: a polygon in the horizontal plane between two
//! heights (a vertical prism), as keep-out zones of the airspace and focus
//! regions of an inspection (where a stricter View model applies) are
//! given.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::setting::Key;
use crate::view::{ViewModel, ViewSettings};

/// A region that cannot be used, named as the user gave it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: '{name}' {problem}")]
pub struct RegionError {
    /// The setting that gave it.
    pub key: Key,
    pub name: String,
    /// What is wrong: `has 2 corners; an outline needs at least 3`.
    pub problem: String,
}

impl Region {
    /// `Err` naming the region and `key` unless it can be used.
    pub fn check(&self, key: Key) -> Result<(), RegionError> {
        match self.problem() {
            None => Ok(()),
            Some(problem) => Err(RegionError {
                key,
                name: self.name.clone(),
                problem,
            }),
        }
    }
}

impl FocusModel {
    /// `Err` naming the region and `key` unless its region and View model
    /// can be used.
    pub fn check(&self, key: Key) -> Result<(), RegionError> {
        self.region.check(key)?;
        self.view.check().map_err(|e| RegionError {
            key,
            name: self.region.name.clone(),
            problem: format!("has a View model that cannot work: {e}"),
        })
    }
}

/// A place to look harder (a bearing, a girder end, a known defect): the
/// target voxels whose centres are in `region` are judged, and planned
/// for, under `view` over the run's View model (a finer GSD, more views).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Focus {
    pub region: Region,
    /// The settings of `[view]` that differ here.
    pub view: ViewSettings,
}

crate::inline_table_setting!(
    Focus,
    "a focus region {region = {name = \"...\", outline = [[x, y], ...]}, view = {max_gsd_mm = ...}}"
);

/// Each focus region with the View model it makes of `base`, first listed
/// first: where regions overlap, the first holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FocusModel {
    pub region: Region,
    pub view: ViewModel,
}

impl FocusModel {
    pub fn of(focus: &[Focus], base: ViewModel) -> Vec<Self> {
        focus
            .iter()
            .map(|f| Self {
                region: f.region.clone(),
                view: f.view.apply(base),
            })
            .collect()
    }

    /// Which of `models` holds `p` (its index), if any.
    pub fn holding(models: &[Self], p: &Point3<f64>) -> Option<usize> {
        models.iter().position(|m| m.region.contains(p))
    }
}

/// A vertical prism in the map frame: the points above `outline` (x, y)
/// between `bottom_m` and `top_m` (map z). A missing height leaves that
/// side open: neither is a column from the ground to the sky.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// What it is, as reports and messages name it.
    pub name: String,
    /// Corners (x, y) in the map frame, metres, in order around; at least
    /// three, the last joined to the first.
    pub outline: Vec<[f64; 2]>,
    /// Lowest height, metres in the map frame [default: none, from below].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bottom_m: Option<f64>,
    /// Highest height, metres in the map frame [default: none, to the sky].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub top_m: Option<f64>,
}

crate::inline_table_setting!(
    Region,
    "a region {name = \"...\", outline = [[x, y], ...], bottom_m = ..., top_m = ...}"
);

impl Region {
    /// Why the region cannot be used, if it cannot.
    pub fn problem(&self) -> Option<String> {
        let finite = |v: &Option<f64>| v.is_none_or(f64::is_finite);
        if self.outline.len() < 3 {
            Some(format!(
                "has {} corners; an outline needs at least 3",
                self.outline.len()
            ))
        } else if !self.outline.iter().flatten().all(|v| v.is_finite())
            || !finite(&self.bottom_m)
            || !finite(&self.top_m)
        {
            Some("has a coordinate that is not a finite number".into())
        } else if let (Some(b), Some(t)) = (self.bottom_m, self.top_m)
            && b >= t
        {
            Some(format!("has bottom_m {b} at or above top_m {t}"))
        } else {
            None
        }
    }

    /// Whether it is a column from the ground to the sky (no heights).
    pub fn is_column(&self) -> bool {
        self.bottom_m.is_none() && self.top_m.is_none()
    }

    /// Whether `p` is inside or on the boundary.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        self.within_heights(p.z) && self.outline_holds([p.x, p.y])
    }

    /// Whether any point of the segment from `a` to `b` is inside or on
    /// the boundary.
    pub fn meets_segment(&self, a: &Point3<f64>, b: &Point3<f64>) -> bool {
        let Some((t0, t1)) = self.heights_span(a.z, b.z) else {
            return false;
        };
        let at = |t: f64| [a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t];
        let (p, q) = (at(t0), at(t1));
        self.outline_holds(p)
            || self.outline_holds(q)
            || self.edges().any(|(c, d)| segments_meet(p, q, c, d))
    }

    fn within_heights(&self, z: f64) -> bool {
        self.bottom_m.is_none_or(|b| z >= b) && self.top_m.is_none_or(|t| z <= t)
    }

    /// The part `[t0, t1]` of the segment (as fractions from `a` to `b`)
    /// within the heights, if any.
    fn heights_span(&self, za: f64, zb: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let dz = zb - za;
        for (limit, below) in [(self.bottom_m, true), (self.top_m, false)] {
            let Some(h) = limit else { continue };
            if dz == 0.0 {
                if (below && za < h) || (!below && za > h) {
                    return None;
                }
                continue;
            }
            let t = (h - za) / dz;
            // Rising through the bottom (or falling through the top) enters.
            if (dz > 0.0) == below {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    fn edges(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        let n = self.outline.len();
        (0..n).map(move |i| (self.outline[i], self.outline[(i + 1) % n]))
    }

    /// Whether the outline holds the point (x, y): inside by the even-odd
    /// rule, or on an edge.
    fn outline_holds(&self, p: [f64; 2]) -> bool {
        let mut inside = false;
        for (c, d) in self.edges() {
            if segments_meet(p, p, c, d) {
                return true;
            }
            if (c[1] > p[1]) != (d[1] > p[1]) {
                let x = c[0] + (p[1] - c[1]) * (d[0] - c[0]) / (d[1] - c[1]);
                if p[0] < x {
                    inside = !inside;
                }
            }
        }
        inside
    }
}

/// Whether the closed segments pq and cd share a point.
fn segments_meet(p: [f64; 2], q: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    // Whether r, known to be on the line through a and b, is between them.
    let between = |a: [f64; 2], b: [f64; 2], r: [f64; 2]| {
        r[0] >= a[0].min(b[0])
            && r[0] <= a[0].max(b[0])
            && r[1] >= a[1].min(b[1])
            && r[1] <= a[1].max(b[1])
    };
    let (d1, d2) = (cross(c, d, p), cross(c, d, q));
    let (d3, d4) = (cross(p, q, c), cross(p, q, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && between(c, d, p))
        || (d2 == 0.0 && between(c, d, q))
        || (d3 == 0.0 && between(p, q, c))
        || (d4 == 0.0 && between(p, q, d))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An L-shaped outline (not convex), 1 to 3 m high.
    fn l_shape() -> Region {
        Region {
            name: "L".into(),
            outline: vec![
                [0.0, 0.0],
                [4.0, 0.0],
                [4.0, 1.0],
                [1.0, 1.0],
                [1.0, 4.0],
                [0.0, 4.0],
            ],
            bottom_m: Some(1.0),
            top_m: Some(3.0),
        }
    }

    #[test]
    fn points_inside_on_and_outside() {
        let r = l_shape();
        assert!(r.contains(&Point3::new(0.5, 3.0, 2.0)));
        assert!(r.contains(&Point3::new(3.0, 0.5, 1.0)), "on the bottom");
        assert!(r.contains(&Point3::new(4.0, 0.5, 2.0)), "on an edge");
        assert!(!r.contains(&Point3::new(2.0, 2.0, 2.0)), "in the L's notch");
        assert!(!r.contains(&Point3::new(0.5, 0.5, 3.5)), "above");
        assert!(!r.contains(&Point3::new(0.5, 0.5, 0.5)), "below");
        let column = Region {
            bottom_m: None,
            top_m: None,
            ..l_shape()
        };
        assert!(column.is_column());
        assert!(column.contains(&Point3::new(0.5, 0.5, -100.0)));
    }

    #[test]
    fn segments_that_cross_touch_pass_over_or_miss() {
        let r = l_shape();
        let p = |x, y, z| Point3::new(x, y, z);
        // Straight through the lower arm, both ends outside.
        assert!(r.meets_segment(&p(2.0, -1.0, 2.0), &p(2.0, 2.0, 2.0)));
        // Across the notch, outside the outline.
        assert!(!r.meets_segment(&p(2.0, 3.0, 2.0), &p(3.0, 2.0, 2.0)));
        // Over the top, then diving through it inside the outline.
        assert!(!r.meets_segment(&p(-1.0, 0.5, 3.5), &p(5.0, 0.5, 3.5)));
        assert!(r.meets_segment(&p(-1.0, 0.5, 5.0), &p(3.0, 0.5, 2.5)));
        // Descending over the outline but above the top until beyond it.
        assert!(!r.meets_segment(&p(0.5, 0.5, 5.0), &p(12.0, 0.5, 0.0)));
        // Touching a corner.
        assert!(r.meets_segment(&p(5.0, -1.0, 2.0), &p(3.0, 1.0, 2.0)));
        // Vertical, through the heights, inside.
        assert!(r.meets_segment(&p(0.5, 0.5, 0.0), &p(0.5, 0.5, 10.0)));
    }

    #[test]
    fn a_region_reads_as_a_toml_inline_table() {
        let r: Region = "{name = \"L\", outline = [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]], bottom_m = 1, top_m = 3}"
            .parse()
            .unwrap();
        assert_eq!(r, l_shape());
        let e = "{name = \"L\", outlines = []}"
            .parse::<Region>()
            .unwrap_err();
        assert!(e.contains("unknown field `outlines`"), "{e}");
    }

    #[test]
    fn a_focus_region_makes_its_view_model_over_the_base() {
        let f: Focus =
            "{region = {name = \"L\", outline = [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]], bottom_m = 1, top_m = 3}, view = {max_gsd_mm = 1.5, views_required = 2}}"
                .parse()
                .unwrap();
        let base = ViewModel::default();
        let models = FocusModel::of(&[f], base);
        assert_eq!(models[0].view.max_gsd_mm, 1.5);
        assert_eq!(models[0].view.views_required, 2);
        assert_eq!(models[0].view.max_distance_m, base.max_distance_m);
        assert_eq!(
            FocusModel::holding(&models, &Point3::new(0.5, 3.0, 2.0)),
            Some(0)
        );
        assert_eq!(
            FocusModel::holding(&models, &Point3::new(2.0, 2.0, 2.0)),
            None
        );
        let e = "{region = {name = \"L\", outline = []}, view = {max_gsd = 1}}"
            .parse::<Focus>()
            .unwrap_err();
        assert!(e.contains("unknown field `max_gsd`"), "{e}");
    }

    #[test]
    fn unusable_regions_say_why() {
        let mut r = l_shape();
        assert_eq!(r.problem(), None);
        r.top_m = Some(0.5);
        assert!(
            r.problem()
                .unwrap()
                .contains("bottom_m 1 at or above top_m 0.5")
        );
        r.outline.truncate(2);
        assert!(r.problem().unwrap().contains("at least 3"));
    }
}
