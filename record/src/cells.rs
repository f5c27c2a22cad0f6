//! An element laid out in cells of its unit, from its target voxels: an
//! area element (a deck, a slab) as square cells of `[record] cell_m` on
//! its plan, a linear one (a girder, a wall, a cap) as short stretches
//! along it (an eighth of `cell_m`), an element counted each as one cell.
//! Each cell holds the quantity of the element it covers (square metres of
//! plan, metres along, or the one element) and whether the flight
//! inspected it.
//!
//! A crack on an area element affects the cells its line crosses; on a
//! linear one the stretch it spans along the element, at least `cell_m`
//! long (a crack across a girder still affects a foot of it).
//!
//! Plan cells are found on a finer grid (a quarter of a cell), each fine
//! square the element's where one of its voxels covers its centre, so that
//! the quantity is the element's footprint to a fraction of a cell, however
//! the voxels lie against the cells.

use std::collections::{BTreeMap, HashMap};

use nalgebra::{Point3, Vector2};
use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::outputs::record::Unit;

/// A cell's place in its element's layout: `(along, across)` on a plan,
/// `(stretch, 0)` along an element, `(0, 0)` for an element counted each.
pub type CellKey = (i64, i64);

/// One cell of an element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The element's quantity in it.
    pub quantity: f64,
    /// Whether the flight inspected it: at least half of the exposed
    /// voxels over it were inspected.
    pub inspected: bool,
}

/// A target voxel as the layout needs it.
#[derive(Debug, Clone, Copy)]
pub struct Voxel {
    pub index: VoxelIndex,
    pub inspected: bool,
    /// It has a face open to the air (voxels inside the structure are
    /// never seen and do not count against a cell's inspection).
    pub exposed: bool,
}

/// How points map onto the cells.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Frame {
    /// Plan cells, `along` the axis and across it.
    Plan { along: Vector2<f64> },
    /// Stretches along a horizontal axis.
    Along { along: Vector2<f64> },
    /// One cell.
    Whole,
}

/// An element's cells.
#[derive(Debug, Clone)]
pub struct Cells {
    pub unit: Unit,
    pub cell_m: f64,
    frame: Frame,
    pub cells: BTreeMap<CellKey, Cell>,
}

/// Fine squares per cell side on a plan; stretches per `cell_m` along.
const PLAN_FINE: i64 = 4;
const ALONG_FINE: i64 = 8;

impl Cells {
    /// The cells of an element of `unit` made of `voxels` on `grid`;
    /// `axis` is the direction along it (unit, horizontal).
    pub fn lay(
        unit: Unit,
        grid: &VoxelGrid,
        voxels: &[Voxel],
        axis: Vector2<f64>,
        cell_m: f64,
    ) -> Self {
        let (frame, cells) = match unit {
            Unit::SquareMetres => (
                Frame::Plan { along: axis },
                plan_cells(grid, voxels, axis, cell_m),
            ),
            Unit::Metres => (
                Frame::Along { along: axis },
                along_cells(grid, voxels, axis, cell_m),
            ),
            Unit::Each => {
                let cell = Cell {
                    quantity: 1.0,
                    inspected: seen_share(voxels.iter()) >= 0.5,
                };
                (Frame::Whole, BTreeMap::from([((0, 0), cell)]))
            }
        };
        Self {
            unit,
            cell_m,
            frame,
            cells,
        }
    }

    /// The element's quantity: its cells'.
    pub fn total(&self) -> f64 {
        self.cells.values().map(|c| c.quantity).sum()
    }

    /// The cell `point` is over, or the nearest one beside it (a crack on a
    /// deck's edge, a trace a little off the voxels); `None` further off.
    pub fn cell_at(&self, point: &Point3<f64>) -> Option<CellKey> {
        let key = self.key_of(point);
        if self.cells.contains_key(&key) {
            return Some(key);
        }
        let (a, b) = key;
        let across = match self.frame {
            Frame::Plan { .. } => -1..=1,
            _ => 0..=0,
        };
        let mut beside = (-1..=1).flat_map(|da| across.clone().map(move |db| (a + da, b + db)));
        beside.find(|k| self.cells.contains_key(k))
    }

    /// The cell key of `point`, whether the element has it or not.
    fn key_of(&self, point: &Point3<f64>) -> CellKey {
        let cell = |x: f64| (x / self.cell_m).floor() as i64;
        match self.frame {
            Frame::Plan { along } => {
                let (a, c) = plan_coordinates(along, point.xy().coords);
                (cell(a), cell(c))
            }
            Frame::Along { along } => (self.stretch(along.dot(&point.xy().coords)), 0),
            Frame::Whole => (0, 0),
        }
    }

    /// The stretch of a linear element at `a` metres along its axis.
    fn stretch(&self, a: f64) -> i64 {
        (a / (self.cell_m / ALONG_FINE as f64)).floor() as i64
    }

    /// The cells a line through `points` affects: those it crosses on a
    /// plan, its span along a linear element (at least `cell_m` of it), or
    /// the one cell.
    pub fn cells_of_line(&self, points: &[Point3<f64>]) -> Vec<CellKey> {
        let mut keys: Vec<CellKey> =
            match self.frame {
                Frame::Along { along } => {
                    let (lo, hi) = points
                        .iter()
                        .map(|p| along.dot(&p.xy().coords))
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| {
                            (lo.min(a), hi.max(a))
                        });
                    if lo > hi {
                        return Vec::new();
                    }
                    let widen = ((self.cell_m - (hi - lo)) / 2.0).max(0.0);
                    let span = self.stretch(lo - widen)..=self.stretch(hi + widen);
                    let on: Vec<CellKey> = span
                        .map(|k| (k, 0))
                        .filter(|k| self.cells.contains_key(k))
                        .collect();
                    if on.is_empty() {
                        points
                            .iter()
                            .filter_map(|p| self.cell_at(p))
                            .take(1)
                            .collect()
                    } else {
                        on
                    }
                }
                _ => {
                    let step = self.cell_m / 4.0;
                    let mut keys = Vec::new();
                    for pair in points.windows(2) {
                        let (a, b) = (pair[0], pair[1]);
                        let steps = ((b - a).norm() / step).ceil().max(1.0) as usize;
                        keys.extend((0..=steps).filter_map(|i| {
                            self.cell_at(&(a + (b - a) * (i as f64 / steps as f64)))
                        }));
                    }
                    if points.len() == 1 {
                        keys.extend(self.cell_at(&points[0]));
                    }
                    keys
                }
            };
        keys.sort_unstable();
        keys.dedup();
        keys
    }
}

/// A horizontal point's coordinates along `along` and across it (to its
/// left).
fn plan_coordinates(along: Vector2<f64>, xy: Vector2<f64>) -> (f64, f64) {
    let across = Vector2::new(-along.y, along.x);
    (along.dot(&xy), across.dot(&xy))
}

/// The share of `voxels`' exposed ones that were inspected (1 where none is
/// exposed: nothing there could be seen or missed).
fn seen_share<'a>(voxels: impl Iterator<Item = &'a Voxel>) -> f64 {
    let (mut exposed, mut seen) = (0usize, 0usize);
    for v in voxels.filter(|v| v.exposed) {
        exposed += 1;
        seen += usize::from(v.inspected);
    }
    if exposed == 0 {
        1.0
    } else {
        seen as f64 / exposed as f64
    }
}

/// Cells adding up fine pieces: each its quantity and its inspected share.
fn gather(pieces: impl Iterator<Item = (CellKey, f64, f64)>) -> BTreeMap<CellKey, Cell> {
    let mut sums: BTreeMap<CellKey, (f64, f64)> = BTreeMap::new();
    for (key, quantity, share) in pieces {
        let s = sums.entry(key).or_default();
        s.0 += quantity;
        s.1 += quantity * share;
    }
    sums.into_iter()
        .map(|(key, (quantity, seen))| {
            let cell = Cell {
                quantity,
                inspected: seen >= 0.5 * quantity,
            };
            (key, cell)
        })
        .collect()
}

/// Plan cells: fine squares whose centre is over one of the element's
/// voxel columns, each with that column's inspected share.
fn plan_cells(
    grid: &VoxelGrid,
    voxels: &[Voxel],
    along: Vector2<f64>,
    cell_m: f64,
) -> BTreeMap<CellKey, Cell> {
    let mut columns: HashMap<(i32, i32), Vec<Voxel>> = HashMap::new();
    for v in voxels {
        columns
            .entry((v.index.0[0], v.index.0[1]))
            .or_default()
            .push(*v);
    }
    let share: HashMap<(i32, i32), f64> = columns
        .iter()
        .map(|(c, vs)| (*c, seen_share(vs.iter())))
        .collect();
    let fine = cell_m / PLAN_FINE as f64;
    let r = grid.resolution;
    // The fine squares within reach of a column, each looked at once.
    let mut squares: BTreeMap<CellKey, f64> = BTreeMap::new();
    for &(ix, iy) in columns.keys() {
        let centre = grid.center(VoxelIndex([ix, iy, 0])).xy().coords;
        let (a, c) = plan_coordinates(along, centre);
        // A column's corners are at most r/sqrt(2) from its centre.
        let reach = r * std::f64::consts::FRAC_1_SQRT_2;
        let span =
            |x: f64| ((x - reach) / fine).floor() as i64..=((x + reach) / fine).floor() as i64;
        for fa in span(a) {
            for fc in span(c) {
                if squares.contains_key(&(fa, fc)) {
                    continue;
                }
                let (ca, cc) = ((fa as f64 + 0.5) * fine, (fc as f64 + 0.5) * fine);
                let xy = along * ca + Vector2::new(-along.y, along.x) * cc;
                let at = grid.voxel_of(&Point3::new(xy.x, xy.y, grid.origin.z));
                if let Some(s) = share.get(&(at.0[0], at.0[1])) {
                    squares.insert((fa, fc), *s);
                }
            }
        }
    }
    gather(squares.into_iter().map(|((fa, fc), s)| {
        let key = (fa.div_euclid(PLAN_FINE), fc.div_euclid(PLAN_FINE));
        (key, fine * fine, s)
    }))
}

/// Stretches along the element (an eighth of a cell each) whose middle one
/// of its voxels spans, each with the inspected share of the voxels
/// spanning it.
fn along_cells(
    grid: &VoxelGrid,
    voxels: &[Voxel],
    along: Vector2<f64>,
    cell_m: f64,
) -> BTreeMap<CellKey, Cell> {
    let fine = cell_m / ALONG_FINE as f64;
    let r = grid.resolution;
    // A voxel's extent along a horizontal axis at an angle to the grid.
    let half = 0.5 * r * (along.x.abs() + along.y.abs());
    let mut spanning: BTreeMap<i64, Vec<Voxel>> = BTreeMap::new();
    for v in voxels {
        let a = along.dot(&grid.center(v.index).xy().coords);
        let first = ((a - half) / fine - 0.5).ceil() as i64;
        let last = ((a + half) / fine - 0.5).floor() as i64;
        for f in first..=last {
            spanning.entry(f).or_default().push(*v);
        }
    }
    gather(
        spanning
            .iter()
            .map(|(f, vs)| ((*f, 0), fine, seen_share(vs.iter()))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box of voxels `nx` x `ny` x `nz`, 0.5 m each, the first `seen_x`
    /// columns along x inspected; only its outside voxels exposed.
    fn block(nx: i32, ny: i32, nz: i32, seen_x: i32) -> Vec<Voxel> {
        let mut out = Vec::new();
        for x in 0..nx {
            for y in 0..ny {
                for z in 0..nz {
                    let outside =
                        x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                    out.push(Voxel {
                        index: VoxelIndex([x, y, z]),
                        inspected: x < seen_x && outside,
                        exposed: outside,
                    });
                }
            }
        }
        out
    }

    /// The quantity of `cells` inspected.
    fn inspected(cells: &Cells) -> f64 {
        cells
            .cells
            .values()
            .filter(|c| c.inspected)
            .map(|c| c.quantity)
            .sum()
    }

    fn grid() -> VoxelGrid {
        VoxelGrid::new(0.5, Point3::origin())
    }

    #[test]
    fn a_deck_is_its_plan_area_and_half_seen_is_half_inspected() {
        // 30 m x 7 m x 0.5 m, the west 15 m seen.
        let deck = block(60, 14, 2, 30);
        let cells = Cells::lay(Unit::SquareMetres, &grid(), &deck, Vector2::x(), 0.3);
        // 210 m², to the fine squares (7.5 cm) cut at its edges.
        assert!(
            (cells.total() - 210.0).abs() < 0.005 * 210.0,
            "{}",
            cells.total()
        );
        let seen = inspected(&cells);
        assert!((seen - 105.0).abs() <= 0.3 * 7.0, "{seen}");
        // A point on the deck's top is over a cell; one 2 m off it is not.
        assert!(cells.cell_at(&Point3::new(3.0, 3.0, 1.0)).is_some());
        assert!(cells.cell_at(&Point3::new(3.0, 9.0, 1.0)).is_none());
    }

    #[test]
    fn a_plan_turned_to_the_grid_keeps_its_area() {
        let deck = block(40, 10, 1, 40);
        let turned = Vector2::new(1.0, 1.0).normalize();
        let cells = Cells::lay(Unit::SquareMetres, &grid(), &deck, turned, 0.3);
        // 100 m², to the fine squares cut at its edges.
        assert!((cells.total() - 100.0).abs() < 3.0, "{}", cells.total());
    }

    #[test]
    fn a_girder_is_its_length_and_a_column_is_one() {
        let girder = block(60, 1, 2, 20);
        let cells = Cells::lay(Unit::Metres, &grid(), &girder, Vector2::x(), 0.3);
        assert!(
            (cells.total() - 30.0).abs() < 0.3 / 8.0 + 1e-9,
            "{}",
            cells.total()
        );
        let seen = inspected(&cells);
        assert!((seen - 10.0).abs() <= 0.3, "{seen}");
        let column = block(2, 2, 10, 2);
        let one = Cells::lay(Unit::Each, &grid(), &column, Vector2::x(), 0.3);
        assert_eq!(one.total(), 1.0);
        assert!(one.cells[&(0, 0)].inspected);
    }
}
