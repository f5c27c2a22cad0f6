//! The stage's settings: the View model's and the others, each unset one
//! falling back (`or`) to the next source; the binary merges command line
//! over `postflight.toml`'s `[view]` and `[coverage]` tables, and the stage
//! applies the result over the plan's View model and the defaults.

use postflight_core::ViewModel;
use serde::{Deserialize, Serialize};

/// View model settings; unset ones keep the plan's (or the defaults).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewSettings {
    pub cone_apex_deg: Option<f64>,
    pub min_distance_m: Option<f64>,
    pub max_distance_m: Option<f64>,
    pub max_incidence_deg: Option<f64>,
    pub max_blur_px: Option<f64>,
    pub max_gsd_mm: Option<f64>,
    pub views_required: Option<u32>,
}

impl ViewSettings {
    /// `self` over `base`.
    pub fn apply(&self, base: ViewModel) -> ViewModel {
        ViewModel {
            cone_apex_deg: self.cone_apex_deg.unwrap_or(base.cone_apex_deg),
            min_distance_m: self.min_distance_m.unwrap_or(base.min_distance_m),
            max_distance_m: self.max_distance_m.unwrap_or(base.max_distance_m),
            max_incidence_deg: self.max_incidence_deg.unwrap_or(base.max_incidence_deg),
            max_blur_px: self.max_blur_px.unwrap_or(base.max_blur_px),
            max_gsd_mm: self.max_gsd_mm.unwrap_or(base.max_gsd_mm),
            views_required: self.views_required.unwrap_or(base.views_required),
        }
    }

    /// `self` where set, else `other`.
    pub fn or(&self, other: &Self) -> Self {
        Self {
            cone_apex_deg: self.cone_apex_deg.or(other.cone_apex_deg),
            min_distance_m: self.min_distance_m.or(other.min_distance_m),
            max_distance_m: self.max_distance_m.or(other.max_distance_m),
            max_incidence_deg: self.max_incidence_deg.or(other.max_incidence_deg),
            max_blur_px: self.max_blur_px.or(other.max_blur_px),
            max_gsd_mm: self.max_gsd_mm.or(other.max_gsd_mm),
            views_required: self.views_required.or(other.views_required),
        }
    }
}

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
