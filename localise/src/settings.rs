//! The stage's settings, declared once: the `[localise]` table of
//! `postflight.toml` and the flags of `postflight localise`. Localise also
//! judges each view by the View model (`[view]`, core's
//! [`postflight_core::ViewSettings`]).

postflight_core::settings! {
    table = "localise", keys = keys;
    /// `[localise]`: how detections are placed and fused.
    pub struct LocaliseSettings =>
    /// How a localise places and fuses detections.
    struct LocaliseConfig {
        /// Rays end this far from the camera, metres.
        #[arg(long = "max-range", value_name = "METRES")]
        max_range_m: f64 = 30.0,
        /// Views of one crack may be this far apart on the surface, metres:
        /// covers the pose error (the simulator's 2 cm and 0.003 rad put a
        /// crack seen from 5 m about 3 cm off; the default allows three
        /// times that).
        #[arg(long = "link-distance", value_name = "METRES")]
        link_distance_m: f64 = 0.1,
        /// Largest angle between the surfaces of two views of one crack, degrees.
        #[arg(long = "max-normal-angle", value_name = "DEGREES")]
        max_normal_angle_deg: f64 = 30.0,
        /// A candidate's length is traced from its views this far or
        /// closer, metres (farther views measure too coarsely to count,
        /// unless no near view is complete).
        #[arg(long = "length-range", value_name = "METRES")]
        length_range_m: f64 = 5.0,
        /// Share of the surface's brightness a crack's interior lacks, where
        /// no crack of the flight resolves to show it: a crack thinner than
        /// the camera's blur is its darkness summed across it over this
        /// depth (resolved cracks, its own stretches, its photo's or the
        /// flight's, give the share instead).
        #[arg(long = "crack-darkness", value_name = "SHARE")]
        crack_darkness: f64 = 0.85,
        /// The camera's blur, one standard deviation in pixels, as declared
        /// for its lens and sensor (from a test chart: 0.187 over its MTF50
        /// in cycles per pixel), where the flight's own cracks cannot show
        /// it (no line thinner than the blur, no resolved crack with walls
        /// apart); without it such a flight's blur is unknown, a middling
        /// 1 px uncertain by half, and its widths carry that.
        #[arg(long = "camera-blur", value_name = "PIXELS")]
        camera_blur_px: f64,
    }
}
