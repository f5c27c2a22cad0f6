//! The comparison's settings, declared once: the `[compare]` table of
//! `postflight.toml` and the flags of `postflight compare`.

use postflight_core::InvalidSetting;

postflight_core::settings! {
    table = "compare", keys = keys;
    /// `[compare]`: how two runs' candidates are matched.
    pub struct CompareSettings =>
    /// How compare matches the two runs' candidates.
    struct CompareConfig {
        /// Largest gap between two candidates' extents that still matches
        /// them, metres (unset: the wider of the two runs' own link
        /// distance, each `[localise] link_distance_m`).
        #[arg(long = "link-distance", value_name = "METRES")]
        link_distance_m: f64,
    }
}

impl CompareConfig {
    /// Refuse a setting that cannot work.
    pub fn check(&self) -> Result<(), InvalidSetting> {
        match self.link_distance_m {
            Some(m) => InvalidSetting::check(
                m >= 0.0 && m.is_finite(),
                keys::link_distance_m,
                m,
                "0 or more metres, finite",
            ),
            None => Ok(()),
        }
    }
}
