//! A number as an error message shows it: as written where it is of a
//! size people write, in scientific notation where it is not (Rust's `{}`
//! spells 1e308 out in 309 digits).

use std::fmt;

/// `f64` shown for a person: `1e308` and `2.5e-9`, not their 309 and 11
/// digits; `NaN`, `inf` and every ordinary figure as `{}` shows them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown(pub f64);

impl fmt::Display for Shown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
            write!(f, "{v}")
        } else {
            write!(f, "{v:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_figures_are_shown_short() {
        let shown = |v: f64| Shown(v).to_string();
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-2.5e-9), "-2.5e-9");
        assert_eq!(shown(488.25), "488.25");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f64::NEG_INFINITY), "-inf");
    }
}
