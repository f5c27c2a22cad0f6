//! The structure to inspect: which voxels of the map are its targets (a
//! plan's target voxels, the map's voxels inside boxes, or a segmented
//! cloud) and the elements they form (deck, girders, piers, a tower). Found
//! the same way, from the map and the targets, by localise (to name each
//! defect candidate's element and place) and by coverage (each voxel's).
//! The elements' types and place names are core's
//! ([`postflight_core::structure`]), which every reader of the tables uses.

pub mod error;
pub mod segment;
pub mod source;

use postflight_core::FlownPlan;
use postflight_core::map::SlamMap;
use postflight_core::structure::ElementMap;

pub use error::StructureError;
pub use segment::{Segmentation, segment};
pub use source::{TargetVoxels, Targets, plan_targets};

/// The structure's target voxels and their elements.
#[derive(Debug, Clone)]
pub struct Found {
    pub targets: TargetVoxels,
    /// Element of each target voxel, in the targets' order.
    pub elements: Segmentation,
}

impl Found {
    /// The targets `source` names on `map`, grouped into elements.
    pub fn find(
        source: &Targets,
        plan: Option<&FlownPlan>,
        map: &SlamMap,
    ) -> Result<Self, StructureError> {
        let targets = TargetVoxels::load(source, plan, map)?;
        let elements = segment(&map.voxels.grid, &targets.voxels, &targets.labels);
        Ok(Self { targets, elements })
    }

    /// Where points on the map are on the structure.
    pub fn element_map(&self, map: &SlamMap) -> ElementMap {
        ElementMap::new(
            self.elements.structure.clone(),
            map.voxels.grid,
            self.targets
                .voxels
                .iter()
                .copied()
                .zip(self.elements.element_of.iter().copied()),
        )
    }
}
