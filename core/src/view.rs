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

/// The rules, each once: what coverage judges a camera and a face by, and
/// localise a view of a crack. Each gives the rule broken, if any; the
/// band's and limits' edges count as within.
impl ViewModel {
    /// The distance band, camera to face centre (at the camera itself: too
    /// close).
    pub fn distance_miss(&self, distance_m: f64) -> Option<Miss> {
        if distance_m > self.max_distance_m {
            Some(Miss::TooFar)
        } else if distance_m < self.min_distance_m || distance_m < 1e-9 {
            Some(Miss::TooClose)
        } else {
            None
        }
    }

    /// The viewing cone: `off_axis_deg` between the optical axis and the
    /// direction to the face.
    pub fn cone_miss(&self, off_axis_deg: f64) -> Option<Miss> {
        (off_axis_deg > self.cone_apex_deg / 2.0).then_some(Miss::OutOfCone)
    }

    /// The largest incidence: `incidence_deg` between the face's normal and
    /// the direction to the camera.
    pub fn incidence_miss(&self, incidence_deg: f64) -> Option<Miss> {
        (incidence_deg > self.max_incidence_deg).then_some(Miss::TooOblique)
    }

    /// The GSD target ([`ViewModel::gsd_mm`]).
    pub fn gsd_miss(&self, gsd_mm: f64) -> Option<Miss> {
        (gsd_mm > self.max_gsd_mm).then_some(Miss::TooCoarse)
    }

    /// The largest blur streak (`None`: unknown, not judged; an unmeasurable
    /// NaN streak counts as blurred).
    pub fn blur_miss(&self, blur_px: Option<f64>) -> Option<Miss> {
        blur_px
            .is_some_and(|b| b.is_nan() || b > self.max_blur_px)
            .then_some(Miss::Blurred)
    }
}

crate::kind! {
    /// A rule of the View model a view breaks: why a camera does not inspect
    /// a face (coverage), or why a view of a crack is not one to measure by
    /// (localise). Ordered by how far a camera got through the rules, so the
    /// furthest over all cameras is the reason a face was missed.
    pub enum Miss("view rule") {
        /// Beyond the distance band (for a face: no camera ever came that close).
        TooFar = "too_far",
        /// Nearer than the distance band.
        TooClose = "too_close",
        /// Outside the viewing cone.
        OutOfCone = "out_of_cone",
        /// Inside the cone but outside the image (a cone wider than the lens).
        OutsideImage = "outside_image",
        /// Seen more obliquely than the largest incidence, or from behind.
        TooOblique = "too_oblique",
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
