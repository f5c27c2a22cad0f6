//! The stage's settings, declared once: the `[coverage]` table of
//! `postflight.toml` and, with the View model's `[view]` (core's
//! [`postflight_core::ViewSettings`]), the flags of `postflight coverage`.

use postflight_core::region::Focus;

postflight_core::settings! {
    table = "coverage", keys = keys;
    /// `[coverage]`: coverage's settings other than the View model.
    pub struct CoverageSettings =>
    /// How coverage judges besides the View model.
    struct CoverageConfig {
        /// Views a face needs within defect_radius_m of a defect candidate
        /// (defects.json from localise) [default: the View model's views].
        #[arg(long = "views-near-defects", value_name = "N")]
        views_near_defects: u32,
        /// What counts as near a defect candidate, metres.
        #[arg(long = "defect-radius", value_name = "METRES")]
        defect_radius_m: f64 = 1.0,
        /// Exposure assumed for frames that recorded none, seconds.
        #[arg(long = "exposure", value_name = "SECONDS")]
        exposure_s: f64,
        /// Places to look harder, each a region (`name`, `outline` of
        /// `[x, y]` corners, optional `bottom_m` and `top_m`) and the
        /// `[view]` settings that apply there instead: target voxels with
        /// their centre inside are judged (and the follow-up planned)
        /// under that stricter View model. `[[coverage.focus]]` tables, or
        /// the flag once per region as a TOML inline table.
        #[arg(long = "focus", value_name = "FOCUS")]
        focus: Vec<Focus> = Vec::new(),
    }
}
