//! postflight's elements as the owner numbers them: each element's AASHTO
//! number (the owner's `[[record.element]]`, else the default for its
//! kind), its cells and its total quantity (measured, or the owner's
//! inventory quantity, which wins).

use nalgebra::Vector2;
use postflight_core::map::VoxelGrid;
use postflight_core::outputs::coverage::VoxelRecord;
use postflight_core::outputs::record::QuantitySource;
use postflight_core::structure::{Element, ElementKind, Structure, major_axis};

use crate::catalogue::{AashtoElement, element_numbered};
use crate::cells::{Cells, Voxel};
use crate::settings::RecordConfig;

/// One element of the record.
#[derive(Debug, Clone)]
pub struct RecordedElement {
    /// postflight's name.
    pub name: String,
    pub aashto: AashtoElement,
    pub cells: Cells,
    /// The quantity the record gives: the owner's inventory quantity, else
    /// the measured one.
    pub total: f64,
    pub source: QuantitySource,
}

impl RecordedElement {
    /// What one cell's quantity counts for in the record: the inventory
    /// quantity spread over the cells where it differs from the measured.
    pub fn scale(&self) -> f64 {
        let measured = self.cells.total();
        if measured > 0.0 {
            self.total / measured
        } else {
            0.0
        }
    }
}

/// A pier whose footprint is this many times longer than it is thick is a
/// wall (210), else a column (205).
const WALL_ASPECT: f64 = 2.5;

/// An inventory quantity this far from the measured one is worth a warning.
const INVENTORY_WARNING_SHARE: f64 = 0.2;

/// The element's default AASHTO number by its kind and shape; `None` for a
/// kind the manual has no default for (a tower, a named part).
fn default_number(kind: ElementKind, footprint: Footprint) -> Option<u16> {
    match kind {
        ElementKind::Deck => Some(12),
        ElementKind::Girder => Some(110),
        ElementKind::Pier if footprint.length >= WALL_ASPECT * footprint.thickness => Some(210),
        ElementKind::Pier => Some(205),
        ElementKind::Tower | ElementKind::Part => None,
    }
}

/// An element's extent on the plan along its major axis and across it.
#[derive(Debug, Clone, Copy)]
struct Footprint {
    axis: Vector2<f64>,
    length: f64,
    thickness: f64,
}

impl Footprint {
    fn of(grid: &VoxelGrid, voxels: &[Voxel]) -> Self {
        let xy: Vec<Vector2<f64>> = voxels
            .iter()
            .map(|v| grid.center(v.index).xy().coords)
            .collect();
        let axis = major_axis(&xy);
        let across = Vector2::new(-axis.y, axis.x);
        let extent = |dir: Vector2<f64>| {
            let (lo, hi) = xy
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(dir.dot(p)), hi.max(dir.dot(p)))
                });
            (hi - lo).max(0.0) + grid.resolution
        };
        Self {
            axis,
            length: extent(axis),
            thickness: extent(across),
        }
    }
}

/// The structure's elements with AASHTO numbers, each laid out in cells
/// from `voxels` (coverage's rows); a warning for each element left out for
/// want of a number, and where an inventory quantity differs much from the
/// measured one.
pub fn recorded_elements(
    structure: &Structure,
    grid: &VoxelGrid,
    voxels: &[VoxelRecord],
    config: &RecordConfig,
    warnings: &mut Vec<String>,
) -> Vec<RecordedElement> {
    let span = Vector2::new(structure.axis[0], structure.axis[1]);
    let mut recorded = Vec::new();
    for element in &structure.elements {
        let own: Vec<Voxel> = voxels
            .iter()
            .filter(|v| v.element == element.name)
            .map(|v| Voxel {
                index: v.voxel,
                inspected: v.inspected,
                exposed: v.faces_exposed > 0,
            })
            .collect();
        if own.is_empty() {
            continue;
        }
        let footprint = Footprint::of(grid, &own);
        let choice = config.choice_for(&element.name);
        let number = choice
            .map(|c| c.number)
            .or_else(|| default_number(element.kind, footprint));
        let Some(aashto) = number.and_then(element_numbered).copied() else {
            warnings.push(format!(
                "{} has no AASHTO element number (none is the default for a tower or a named part) and is left out of the record; give it one in [[record.element]] (name = {:?}, number = N)",
                element.name, element.name
            ));
            continue;
        };
        let axis = axis_of(element, span, footprint);
        let cells = Cells::lay(aashto.unit, grid, &own, axis, config.cell_m);
        let measured = cells.total();
        let (total, source) = match choice.and_then(|c| c.quantity) {
            Some(q) => {
                if (q - measured).abs() > INVENTORY_WARNING_SHARE * q {
                    warnings.push(format!(
                        "{}: the inventory quantity {q:.1} {} differs from the {measured:.1} {} the flight's map measures by more than {:.0}%; check the element's number and the map",
                        element.name,
                        aashto.unit.as_str(),
                        aashto.unit.as_str(),
                        100.0 * INVENTORY_WARNING_SHARE
                    ));
                }
                (q, QuantitySource::Inventory)
            }
            None => (measured, QuantitySource::Structure),
        };
        recorded.push(RecordedElement {
            name: element.name.clone(),
            aashto,
            cells,
            total,
            source,
        });
    }
    recorded
}

/// The direction an element is measured along: the span for a deck or a
/// girder, its own longest horizontal extent for anything else.
fn axis_of(element: &Element, span: Vector2<f64>, footprint: Footprint) -> Vector2<f64> {
    if element.kind.runs_along_span() {
        span
    } else {
        footprint.axis
    }
}
