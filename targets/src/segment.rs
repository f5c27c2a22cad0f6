//! Elements found from the geometry of the target voxels alone:
//! - a structure at least as tall as it is long is a tower (one per
//!   connected part);
//! - otherwise it is a bridge: voxels on a long run along its span (its
//!   major horizontal axis) are the superstructure, of which the widest
//!   top layers are the deck and the parts below them the girders; the
//!   connected parts under the superstructure are the piers.
//!
//! Piers are numbered along the span from its west end (south end when the
//! span runs north–south), girders across it from its south (east) side.
//! Named target boxes override: their voxels are the element they name.

use std::collections::{BTreeMap, HashMap, HashSet};

use nalgebra::{Vector2, Vector3};
use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::structure::{Element, ElementKind, Structure, major_axis};

/// Target voxels grouped into elements.
#[derive(Debug, Clone)]
pub struct Segmentation {
    pub structure: Structure,
    /// Element of each target voxel, in the order given.
    pub element_of: Vec<usize>,
}

/// Group `targets` into elements; `labels` name the voxels of named target
/// boxes, which override the geometry.
pub fn segment(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    labels: &HashMap<VoxelIndex, String>,
) -> Segmentation {
    let unlabelled: Vec<VoxelIndex> = targets
        .iter()
        .copied()
        .filter(|v| !labels.contains_key(v))
        .collect();
    let axis = span_axis(grid, targets);
    let groups = Groups::find(grid, &unlabelled, axis);
    let mut element_of_voxel: HashMap<VoxelIndex, (String, ElementKind)> = groups.named(grid, axis);
    for (v, name) in labels {
        element_of_voxel.insert(*v, (name.clone(), ElementKind::Part));
    }
    summarise(grid, targets, axis, &element_of_voxel)
}

/// The elements' figures, and each target's element.
fn summarise(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    axis: Vector2<f64>,
    named: &HashMap<VoxelIndex, (String, ElementKind)>,
) -> Segmentation {
    let mut index: BTreeMap<String, usize> = BTreeMap::new();
    let mut elements: Vec<Element> = Vec::new();
    let element_of = targets
        .iter()
        .map(|v| {
            let (name, kind) = &named[v];
            let c = grid.center(*v);
            let base = c.z - grid.resolution / 2.0;
            let along = axis.dot(&c.xy().coords) - grid.resolution / 2.0;
            let i = *index.entry(name.clone()).or_insert_with(|| {
                elements.push(Element {
                    name: name.clone(),
                    kind: *kind,
                    base_z_m: base,
                    start_m: along,
                    voxels: 0,
                });
                elements.len() - 1
            });
            let e = &mut elements[i];
            e.base_z_m = e.base_z_m.min(base);
            e.start_m = e.start_m.min(along);
            e.voxels += 1;
            i
        })
        .collect();
    Segmentation {
        structure: Structure {
            axis: [axis.x, axis.y],
            elements,
        },
        element_of,
    }
}

/// The major horizontal axis of the targets, pointing east (north when it
/// runs north–south).
fn span_axis(grid: &VoxelGrid, targets: &[VoxelIndex]) -> Vector2<f64> {
    let xy: Vec<Vector2<f64>> = targets
        .iter()
        .map(|v| grid.center(*v).xy().coords)
        .collect();
    major_axis(&xy)
}

/// The structure's parts by what they are, before naming.
struct Groups {
    towers: Vec<Vec<VoxelIndex>>,
    deck: Vec<VoxelIndex>,
    /// Along the deck and above it: parapets.
    above_deck: Vec<Vec<VoxelIndex>>,
    girders: Vec<Vec<VoxelIndex>>,
    piers: Vec<Vec<VoxelIndex>>,
}

/// A span run must be this share of the structure's length.
const SPAN_RUN_SHARE: f64 = 0.5;
/// Anything on the deck shorter than this is the deck's own surface.
const PARAPET_MIN_HEIGHT_M: f64 = 0.9;
/// Deck layers hold at least this share of the fullest layer's span voxels.
const DECK_LAYER_SHARE: f64 = 0.6;

impl Groups {
    fn find(grid: &VoxelGrid, voxels: &[VoxelIndex], axis: Vector2<f64>) -> Self {
        let mut groups = Self {
            towers: Vec::new(),
            deck: Vec::new(),
            above_deck: Vec::new(),
            girders: Vec::new(),
            piers: Vec::new(),
        };
        if voxels.is_empty() {
            return groups;
        }
        let set: HashSet<VoxelIndex> = voxels.iter().copied().collect();
        let along = |v: &VoxelIndex| axis.dot(&grid.center(*v).xy().coords);
        let (lo, hi) = min_max(voxels.iter().map(along));
        let length = hi - lo + grid.resolution;
        let (zlo, zhi) = min_max(voxels.iter().map(|v| f64::from(v.0[2])));
        let height = (zhi - zlo + 1.0) * grid.resolution;
        if height >= length {
            groups.towers = columns(components(voxels, &set));
            return groups;
        }
        let min_run = SPAN_RUN_SHARE * length;
        let (span, rest): (Vec<VoxelIndex>, Vec<VoxelIndex>) = voxels
            .iter()
            .partition(|v| run_along(grid, &set, **v, axis) >= min_run);
        let deck_layers = deck_layers(&span);
        let (deck, others): (Vec<VoxelIndex>, Vec<VoxelIndex>) =
            span.iter().partition(|v| deck_layers.contains(&v.0[2]));
        let deck_bottom = deck_layers.iter().min().copied().unwrap_or(i32::MIN);
        let others_set: HashSet<VoxelIndex> = others.iter().copied().collect();
        for part in components(&others, &others_set) {
            let top = part.iter().map(|v| v.0[2]).max().unwrap_or(deck_bottom);
            if part[0].0[2] <= deck_bottom {
                groups.girders.push(part);
            } else if f64::from(top - part[0].0[2] + 1) * grid.resolution >= PARAPET_MIN_HEIGHT_M {
                groups.above_deck.push(part);
            } else {
                // The deck's top surface where it crosses into the next layer.
                groups.deck.extend(part);
            }
        }
        let rest_set: HashSet<VoxelIndex> = rest.iter().copied().collect();
        let span_bottom = span.iter().map(|v| v.0[2]).min().unwrap_or(i32::MIN);
        for part in columns(components(&rest, &rest_set)) {
            // Below the superstructure it is a pier; otherwise a small
            // piece (an end, a bracket) belongs to the deck.
            if part.iter().any(|v| v.0[2] < span_bottom) {
                groups.piers.push(part);
            } else {
                groups.deck.extend(part);
            }
        }
        groups.deck.extend(deck);
        groups
    }

    /// Each voxel's element name and kind.
    fn named(
        self,
        grid: &VoxelGrid,
        axis: Vector2<f64>,
    ) -> HashMap<VoxelIndex, (String, ElementKind)> {
        let across = Vector2::new(-axis.y, axis.x);
        let mean = |part: &[VoxelIndex], dir: Vector2<f64>| {
            part.iter()
                .map(|v| dir.dot(&grid.center(*v).xy().coords))
                .sum::<f64>()
                / part.len() as f64
        };
        let mut out = HashMap::new();
        let mut name_all = |mut parts: Vec<Vec<VoxelIndex>>, dir, word: &str, kind| {
            parts.sort_by(|a, b| mean(a, dir).total_cmp(&mean(b, dir)));
            let numbered = parts.len() > 1;
            for (i, part) in parts.into_iter().enumerate() {
                let name = if numbered {
                    format!("{word} {}", i + 1)
                } else {
                    word.to_string()
                };
                for v in part {
                    out.insert(v, (name.clone(), kind));
                }
            }
        };
        name_all(self.towers, axis, "tower", ElementKind::Tower);
        name_all(self.piers, axis, "pier", ElementKind::Pier);
        name_all(self.girders, across, "girder", ElementKind::Girder);
        name_all(self.above_deck, across, "parapet", ElementKind::Part);
        if !self.deck.is_empty() {
            name_all(vec![self.deck], axis, "deck", ElementKind::Deck);
        }
        out
    }
}

/// Length in metres of the run of voxels through `v` along `axis`, allowing
/// one missing voxel at a time (holes in the map).
fn run_along(
    grid: &VoxelGrid,
    set: &HashSet<VoxelIndex>,
    v: VoxelIndex,
    axis: Vector2<f64>,
) -> f64 {
    let step = Vector3::new(axis.x, axis.y, 0.0) * grid.resolution;
    let centre = grid.center(v);
    let reach = |sign: f64| {
        let (mut last, mut k) = (0, 1);
        while k - last <= 2 {
            if set.contains(&grid.voxel_of(&(centre + step * (sign * f64::from(k))))) {
                last = k;
            }
            k += 1;
        }
        f64::from(last)
    };
    (reach(1.0) + reach(-1.0) + 1.0) * grid.resolution
}

/// The deck's layers: the topmost block of layers holding most of the span voxels.
fn deck_layers(span: &[VoxelIndex]) -> HashSet<i32> {
    let mut count: BTreeMap<i32, usize> = BTreeMap::new();
    for v in span {
        *count.entry(v.0[2]).or_default() += 1;
    }
    let fullest = count.values().copied().max().unwrap_or(0);
    let full = |n: usize| n as f64 >= DECK_LAYER_SHARE * fullest as f64;
    let mut layers = HashSet::new();
    let mut started = false;
    for (&k, &n) in count.iter().rev() {
        if full(n) {
            started = true;
            layers.insert(k);
        } else if started {
            break;
        }
    }
    layers
}

/// Connected parts (26-neighbourhood) of `voxels`, each in the order found.
fn components(voxels: &[VoxelIndex], set: &HashSet<VoxelIndex>) -> Vec<Vec<VoxelIndex>> {
    let mut seen: HashSet<VoxelIndex> = HashSet::new();
    let mut parts = Vec::new();
    for &start in voxels {
        if !seen.insert(start) {
            continue;
        }
        let mut part = vec![start];
        let mut i = 0;
        while i < part.len() {
            for n in part[i].neighbours() {
                if set.contains(&n) && seen.insert(n) {
                    part.push(n);
                }
            }
            i += 1;
        }
        part.sort_by_key(|v| v.0[2]);
        parts.push(part);
    }
    parts
}

/// Parts one above another (footprints overlapping in plan) joined into one
/// column: a tower or pier the map or the plan's targets cut into bands.
fn columns(parts: Vec<Vec<VoxelIndex>>) -> Vec<Vec<VoxelIndex>> {
    let footprint = |part: &[VoxelIndex]| {
        part.iter()
            .fold([i32::MAX, i32::MAX, i32::MIN, i32::MIN], |b, v| {
                [
                    b[0].min(v.0[0]),
                    b[1].min(v.0[1]),
                    b[2].max(v.0[0]),
                    b[3].max(v.0[1]),
                ]
            })
    };
    let mut merged: Vec<(Vec<VoxelIndex>, [i32; 4])> = Vec::new();
    for part in parts {
        let mut fp = footprint(&part);
        let mut part = part;
        // Join every column this part overlaps, until none is left.
        while let Some(i) = merged
            .iter()
            .position(|(_, b)| b[0] <= fp[2] && fp[0] <= b[2] && b[1] <= fp[3] && fp[1] <= b[3])
        {
            let (other, b) = merged.swap_remove(i);
            part.extend(other);
            fp = [
                fp[0].min(b[0]),
                fp[1].min(b[1]),
                fp[2].max(b[2]),
                fp[3].max(b[3]),
            ];
        }
        merged.push((part, fp));
    }
    merged
        .into_iter()
        .map(|(mut part, _)| {
            part.sort_by_key(|v| v.0[2]);
            part
        })
        .collect()
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::Point3;
    use postflight_core::structure::ElementMap;

    use super::*;

    fn cuboid(grid: &VoxelGrid, min: [f64; 3], max: [f64; 3], out: &mut Vec<VoxelIndex>) {
        let lo = grid.voxel_of(&Point3::from(min));
        let hi = grid.voxel_of(&Point3::new(max[0] - 1e-9, max[1] - 1e-9, max[2] - 1e-9));
        for x in lo.0[0]..=hi.0[0] {
            for y in lo.0[1]..=hi.0[1] {
                for z in lo.0[2]..=hi.0[2] {
                    out.push(VoxelIndex([x, y, z]));
                }
            }
        }
    }

    /// Two piers, three girders and a deck, solid.
    fn bridge(grid: &VoxelGrid) -> Vec<VoxelIndex> {
        let mut v = Vec::new();
        for x in [-8.0, 8.0] {
            cuboid(grid, [x - 0.5, -2.5, 0.0], [x + 0.5, 2.5, 5.0], &mut v);
        }
        for y in [-2.0, 0.0, 2.0] {
            cuboid(grid, [-15.0, y - 0.25, 5.0], [15.0, y + 0.25, 6.0], &mut v);
        }
        cuboid(grid, [-15.0, -3.5, 6.0], [15.0, 3.5, 6.5], &mut v);
        v.sort();
        v.dedup();
        v
    }

    fn name_at(s: &Segmentation, targets: &[VoxelIndex], grid: &VoxelGrid, p: [f64; 3]) -> String {
        let v = grid.voxel_of(&Point3::from(p));
        let i = targets.iter().position(|t| *t == v).unwrap();
        s.structure.elements[s.element_of[i]].name.clone()
    }

    #[test]
    fn a_girder_bridge_splits_into_deck_girders_and_numbered_piers() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let targets = bridge(&grid);
        let s = segment(&grid, &targets, &HashMap::new());
        let at = |p| name_at(&s, &targets, &grid, p);
        assert_eq!(at([-8.2, 0.1, 2.0]), "pier 1");
        assert_eq!(at([8.2, 0.1, 2.0]), "pier 2");
        assert_eq!(at([0.1, -2.1, 5.2]), "girder 1");
        assert_eq!(at([0.1, 0.1, 5.2]), "girder 2");
        assert_eq!(at([0.1, 2.1, 5.7]), "girder 3");
        assert_eq!(at([0.1, 3.0, 6.2]), "deck");
        assert_eq!(s.structure.elements.len(), 6);
        assert!((s.structure.axis[0] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_tall_cylinder_is_a_tower_named_by_compass_and_height() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let mut targets = Vec::new();
        cuboid(&grid, [-2.0, -2.0, 0.0], [2.0, 2.0, 12.0], &mut targets);
        let s = segment(&grid, &targets, &HashMap::new());
        assert_eq!(s.structure.elements.len(), 1);
        let map = ElementMap::new(
            s.structure.clone(),
            grid,
            targets.iter().copied().zip(s.element_of.iter().copied()),
        );
        let place = map
            .place(&Point3::new(1.5, 1.5, 7.2), &Vector3::new(1.0, 1.0, 0.1))
            .unwrap();
        assert_eq!(
            place.to_string(),
            "tower, north-east face, 7.2 m above its base"
        );
    }

    #[test]
    fn a_tower_cut_into_bands_is_one_tower() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let mut targets = Vec::new();
        for z in [0.0, 4.0, 8.0] {
            cuboid(&grid, [-2.0, -2.0, z], [2.0, 2.0, z + 3.0], &mut targets);
        }
        let s = segment(&grid, &targets, &HashMap::new());
        assert_eq!(s.structure.elements.len(), 1);
        assert_eq!(s.structure.elements[0].name, "tower");
    }

    #[test]
    fn deck_places_are_measured_from_the_west_end_and_its_underside_is_the_soffit() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let targets = bridge(&grid);
        let s = segment(&grid, &targets, &HashMap::new());
        let map = ElementMap::new(
            s.structure.clone(),
            grid,
            targets.iter().copied().zip(s.element_of.iter().copied()),
        );
        let soffit = map
            .place(&Point3::new(-3.0, 1.0, 6.0), &-Vector3::z())
            .unwrap();
        assert_eq!(soffit.to_string(), "deck, soffit, 12.0 m from its west end");
        let pier = map
            .place(&Point3::new(8.5, 0.0, 1.4), &Vector3::x())
            .unwrap();
        assert_eq!(pier.to_string(), "pier 2, east face, 1.4 m above its base");
        assert!(
            map.place(&Point3::new(0.0, 20.0, 0.0), &Vector3::z())
                .is_none()
        );
    }

    #[test]
    fn named_boxes_override_the_geometry() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let targets = bridge(&grid);
        let labels: HashMap<VoxelIndex, String> = targets
            .iter()
            .filter(|v| grid.center(**v).x > 7.0 && grid.center(**v).z < 5.0)
            .map(|v| (*v, "pier P2 (river)".to_string()))
            .collect();
        let s = segment(&grid, &targets, &labels);
        assert_eq!(
            name_at(&s, &targets, &grid, [8.2, 0.1, 2.0]),
            "pier P2 (river)"
        );
        assert_eq!(name_at(&s, &targets, &grid, [-8.2, 0.1, 2.0]), "pier");
    }
}
