//! The View model: when a voxel face counts as inspected by a frame
//! (GATSBI's, with the Zhao et al. view count; defaults are GATSBI's), and
//! its settings, the `[view]` table of `postflight.toml`, which localise and
//! coverage both judge views by.

use crate::Intrinsics;
use crate::setting::InvalidSetting;

crate::settings! {
    table = "view", keys = keys;
    /// `[view]`: the View model; an unset setting keeps the plan's (or the
    /// default).
    #[derive(Copy)]
    pub struct ViewSettings =>
    /// When a voxel face counts as inspected by a frame.
    #[derive(Copy)]
    struct ViewModel {
        /// Apex angle of the viewing cone around the optical axis, degrees.
        #[arg(long = "cone-apex", value_name = "DEGREES")]
        cone_apex_deg: f64 = 20.0,
        /// Near edge of the distance band from the camera to the face centre, metres.
        #[arg(long = "min-distance", value_name = "METRES")]
        min_distance_m: f64 = 2.0,
        /// Far edge of the distance band, metres.
        #[arg(long = "max-distance", value_name = "METRES")]
        max_distance_m: f64 = 5.0,
        /// Largest angle between a face's normal and the direction to the camera, degrees.
        #[arg(long = "max-incidence", value_name = "DEGREES")]
        max_incidence_deg: f64 = 60.0,
        /// Largest motion blur streak of a usable frame, pixels.
        #[arg(long = "max-blur", value_name = "PIXELS")]
        max_blur_px: f64 = 3.0,
        /// Coarsest ground sampling distance of a usable view, mm per pixel.
        #[arg(long = "max-gsd", value_name = "MM")]
        max_gsd_mm: f64 = 6.0,
        /// Views a face needs to count as inspected.
        #[arg(long = "views", value_name = "N")]
        views_required: u32 = 1,
    }
}

impl ViewSettings {
    /// `self` over `base` (a plan's View model, or the defaults).
    pub fn apply(&self, base: ViewModel) -> ViewModel {
        self.over(&base.into()).resolve()
    }
}

impl ViewModel {
    /// The View model's GSD: a pixel's fronto-parallel footprint at
    /// `distance_m` through lens `k` (its finer axis), millimetres.
    pub fn gsd_mm(distance_m: f64, k: &Intrinsics) -> f64 {
        distance_m * 1000.0 / k.fx.min(k.fy)
    }

    /// Refuse a View model that cannot work.
    pub fn check(&self) -> Result<(), InvalidSetting> {
        InvalidSetting::check(
            self.min_distance_m >= 0.0
                && self.min_distance_m < self.max_distance_m
                && self.max_distance_m.is_finite(),
            keys::min_distance_m,
            self.min_distance_m,
            &format!(
                "at least 0 and below the distance band's far edge ({} {}), both finite",
                keys::max_distance_m,
                self.max_distance_m
            ),
        )?;
        InvalidSetting::check(
            self.cone_apex_deg > 0.0 && self.cone_apex_deg <= 180.0,
            keys::cone_apex_deg,
            self.cone_apex_deg,
            "in (0, 180] degrees",
        )?;
        InvalidSetting::check(
            self.max_incidence_deg > 0.0 && self.max_incidence_deg <= 90.0,
            keys::max_incidence_deg,
            self.max_incidence_deg,
            "in (0, 90] degrees",
        )?;
        InvalidSetting::check(
            self.max_blur_px >= 0.0 && self.max_blur_px.is_finite(),
            keys::max_blur_px,
            self.max_blur_px,
            "0 or more pixels, finite",
        )?;
        InvalidSetting::check(
            self.max_gsd_mm > 0.0 && self.max_gsd_mm.is_finite(),
            keys::max_gsd_mm,
            self.max_gsd_mm,
            "a positive number of millimetres",
        )?;
        InvalidSetting::check(
            (1..=Self::MAX_VIEWS_REQUIRED).contains(&self.views_required),
            keys::views_required,
            self.views_required,
            &format!(
                "1 to {} views (replan plans that many viewpoints for each face it must cover)",
                Self::MAX_VIEWS_REQUIRED
            ),
        )
    }

    /// More views of a face than any inspection asks for (two or three;
    /// photogrammetry a dozen): replan's work grows with it.
    pub const MAX_VIEWS_REQUIRED: u32 = 64;
}

crate::kind! {
    /// Why a camera does not inspect a face. Ordered by how far the camera got
    /// through the rules, so the furthest over all cameras is the reason a
    /// face was missed.
    pub enum Miss("view rule") {
        /// Beyond the distance band (for a face: no camera ever came that close).
        TooFar = "too_far",
        TooClose = "too_close",
        /// Outside the viewing cone.
        OutOfCone = "out_of_cone",
        /// Inside the cone but outside the image (a cone wider than the lens).
        OutsideImage = "outside_image",
        /// The face points away, or is seen more obliquely than the largest incidence.
        BackFacing = "back_facing",
        /// Ground sampling distance coarser than the target.
        TooCoarse = "too_coarse",
        /// Another occupied voxel is in the line of sight.
        Occluded = "occluded",
        /// The frame is motion-blurred beyond the threshold.
        Blurred = "blurred",
        /// Seen, but by fewer usable views than the face needs.
        TooFewViews = "too_few_views",
    }
}
