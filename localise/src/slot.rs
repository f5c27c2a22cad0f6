//! The model of a crossing a width is read by: a slot, a rectangle of the
//! crack's interior darkness as wide as its opening, seen through the
//! camera's blur (a Gaussian). Blurred, a slot's walls stay where they
//! were at half its depth while it is several blurs wide; a narrower one
//! never reaches its interior's darkness and spreads to the blur's own
//! width. The model says, for an opening `w` and a blur `sigma`, how wide
//! the blurred slot reads at half its (blurred) depth, and the other way:
//! the opening a half-depth width means.

use std::sync::LazyLock;

/// A Gaussian's width at half its height over its standard deviation: what
/// a line much thinner than the blur reads at half depth, in blurs.
pub const THIN_FWHM_SIGMAS: f64 = 2.354_820_045;
/// Openings the table spans, in blurs; wider ones read their opening.
const TABLE_SIGMAS: f64 = 12.0;
/// Table steps per blur.
const TABLE_STEPS: f64 = 100.0;

/// The width at half its depth of a slot `openings` blurs wide, in blurs:
/// the blur's own [`THIN_FWHM_SIGMAS`] for a line, the opening for a wide
/// slot.
pub fn half_depth_width(openings: f64) -> f64 {
    if openings >= TABLE_SIGMAS {
        return openings;
    }
    // A line: the blur's own (the slot's darkness vanishes with it).
    let u = openings.max(1e-6);
    // Darkness at offset x from the middle, in blurs, of a slot of unit
    // interior darkness: the rectangle's share the Gaussian takes in.
    let dark = |x: f64| {
        0.5 * (libm::erf((x + u / 2.0) / std::f64::consts::SQRT_2)
            - libm::erf((x - u / 2.0) / std::f64::consts::SQRT_2))
    };
    let half = dark(0.0) / 2.0;
    // The half-depth point lies between the middle and the wall plus
    // three blurs; the darkness falls monotonically out there.
    let (mut lo, mut hi) = (0.0, u / 2.0 + 3.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if dark(mid) > half {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo + hi
}

/// [`half_depth_width`] at `TABLE_STEPS` a blur, from none to
/// [`TABLE_SIGMAS`]: rising, so its inverse is read off it.
static TABLE: LazyLock<Vec<f64>> = LazyLock::new(|| {
    let n = (TABLE_SIGMAS * TABLE_STEPS) as usize;
    (0..=n)
        .map(|i| half_depth_width(i as f64 / TABLE_STEPS))
        .collect()
});

/// The opening, in pixels, of the slot that reads `half_px` wide at half
/// depth through a blur of `sigma_px`; `None` where that is no wider than
/// the blur alone spreads a line (the opening is then the darkness's to
/// say).
pub fn opening(half_px: f64, sigma_px: f64) -> Option<f64> {
    if sigma_px <= 0.0 {
        return Some(half_px);
    }
    let x = half_px / sigma_px;
    let table = &*TABLE;
    if x <= table[0] {
        return None;
    }
    if x >= table[table.len() - 1] {
        return Some(half_px);
    }
    let i = table.partition_point(|h| *h < x);
    let (h0, h1) = (table[i - 1], table[i]);
    let u = (i as f64 - 1.0 + (x - h0) / (h1 - h0)) / TABLE_STEPS;
    Some(u * sigma_px)
}

/// How much the opening [`opening`] reads changes for a change of the blur,
/// pixels of opening per pixel of blur (negative: a larger blur means a
/// narrower opening for the same half-depth width).
pub fn opening_per_blur(half_px: f64, sigma_px: f64) -> f64 {
    let step = 0.02 * sigma_px.max(0.05);
    let at = |s: f64| opening(half_px, s).unwrap_or(0.0);
    (at(sigma_px + step) - at((sigma_px - step).max(0.0))) / (2.0 * step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_reads_the_blur_and_a_wide_slot_its_opening() {
        assert!((half_depth_width(0.0) - THIN_FWHM_SIGMAS).abs() < 1e-6);
        assert!((half_depth_width(8.0) - 8.0).abs() < 0.01);
        // Three blurs wide: the half depth reads wider by a tenth.
        let three = half_depth_width(3.0);
        assert!(three > 3.2 && three < 3.45, "{three}");
    }

    #[test]
    fn the_opening_inverts_the_half_depth_width() {
        for (w, sigma) in [(1.5, 0.6), (2.5, 0.85), (4.0, 1.2), (9.0, 2.0), (40.0, 1.0)] {
            let half = sigma * half_depth_width(w / sigma);
            let back = opening(half, sigma).unwrap();
            assert!((back - w).abs() < 0.01, "{w} px through {sigma}: {back}");
        }
        assert_eq!(opening(2.0, 0.9), None);
        assert_eq!(opening(3.0, 0.0), Some(3.0));
        // A larger blur: a narrower opening for the same half depth.
        assert!(opening_per_blur(3.0, 0.85) < -0.5);
        assert!(opening_per_blur(30.0, 0.85).abs() < 1e-6);
    }
}
