//! The stage's settings: the View model's and the others, each unset one
//! falling back (`or`) to the next source; the binary merges command line
//! over `postflight.toml`'s `[view]` and `[coverage]` tables, and the stage
//! applies the result over the plan's View model and the defaults.

pub use postflight_core::ViewSettings;
use serde::{Deserialize, Serialize};

/// Settings of the stage other than the View model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CoverageSettings {
    /// Views a face needs within `defect_radius_m` of a defect candidate.
    pub views_near_defects: Option<u32>,
    pub defect_radius_m: Option<f64>,
    /// Exposure assumed for frames that did not record one, seconds.
    pub exposure_s: Option<f64>,
}

impl CoverageSettings {
    pub fn or(&self, other: &Self) -> Self {
        Self {
            views_near_defects: self.views_near_defects.or(other.views_near_defects),
            defect_radius_m: self.defect_radius_m.or(other.defect_radius_m),
            exposure_s: self.exposure_s.or(other.exposure_s),
        }
    }
}
