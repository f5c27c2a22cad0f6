//! A crack's cross-section as real ones look, for the flights made to
//! measure width (`--crack-widths`): from a V to a U, its depth (how much
//! light its interior lacks) varying along it, its opening ragged along
//! it, its edges spalled (a shallow, chipped shoulder either side) and
//! stretches filled with dirt, and the narrower the opening the darker
//! its interior (a slot, whose depth the light does not reach). Its width
//! is the opening's, as an inspector's gauge reads it; the spalls and the dirt are what a profile
//! of grey levels can take for more or less crack. Each crack's section
//! is drawn from its id, so a flight keeps its seeds' other draws.

use crate::rng::hash3;

/// How one crack's section looks and varies along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    /// 0 for a flat-bottomed U, 1 for a V: the share of the half-width
    /// over which the interior ramps up to its full depth from the edge.
    pub vee: f64,
    /// Share of the surface's light the interior lacks at its deepest.
    pub depth: f64,
    /// How much the opening varies along the crack, as a share of it.
    pub ragged: f64,
    /// A spalled shoulder this many half-widths wide beyond each edge, and
    /// the share of light it lacks at the edge (fading to none).
    pub spall: f64,
    pub spall_depth: f64,
    /// Below this, the dirt's noise along the crack fills it (its interior
    /// a third as dark): up to about a fifth of its length, in stretches
    /// of centimetres.
    pub dirt: f64,
    salt: u64,
}

/// An opening this wide is half a slot: its interior's darkness half way
/// from its section's to [`SLOT_DEPTH`] throughout, flat-bottomed half
/// way from its section's V. Light reaches the bottom of a wide crack but
/// not of a narrow one as deep: real cracks darken as they narrow.
/// Crack500's cracks, their darkness summed across them over their drawn
/// width, sum to 0.85 to 1.05 of it where drawn 1 to 3 px wide, 0.59 to
/// 0.68 at 3 to 5 px, 0.33 to 0.53 at 5 to 15 px (both halves,
/// `scripts/real_cracks.py darkness`); its pixel's size is not published
/// (phone photos resized to 640 x 360), so this takes it as about a
/// millimetre, the size the measurement flights shoot at.
const SLOT_M: f64 = 0.002;
/// The share of light a slot's interior lacks.
const SLOT_DEPTH: f64 = 0.95;

/// Wavelength of the variations along the crack, metres.
const ALONG_M: f64 = 0.02;
/// Wavelength of the dirt's stretches along the crack, metres.
const DIRT_M: f64 = 0.1;

impl Section {
    /// The section of crack `id`.
    pub fn of(id: u32) -> Self {
        let h = |k: i64| hash3(i64::from(id), k, 0, 0x5ec7);
        Self {
            vee: h(1),
            depth: 0.55 + 0.35 * h(2),
            ragged: 0.3 * h(3),
            spall: 1.5 * h(4) * h(4),
            spall_depth: 0.08 + 0.17 * h(5),
            dirt: 0.2 * h(6),
            salt: u64::from(id) << 8,
        }
    }

    /// Smooth noise in [0, 1] at arc length `s` along line `line`, varying
    /// over `wavelength` metres.
    fn varying(&self, line: usize, s: f64, channel: u64, wavelength: f64) -> f64 {
        let q = s / wavelength;
        let (i, f) = (q.floor(), q - q.floor());
        let at = |k: f64| hash3(k as i64, line as i64, 0, self.salt ^ channel);
        let f = f * f * (3.0 - 2.0 * f);
        at(i) * (1.0 - f) + at(i + 1.0) * f
    }

    /// [`Self::varying`] over [`ALONG_M`].
    fn along(&self, line: usize, s: f64, channel: u64) -> f64 {
        self.varying(line, s, channel, ALONG_M)
    }

    /// The opening's factor at arc length `s` of line `line`: between
    /// 1 - `ragged` and 1, so the crack is never wider than its widest.
    pub fn opening(&self, line: usize, s: f64) -> f64 {
        1.0 - self.ragged * self.along(line, s, 1)
    }

    /// Share of light missing at `x` metres across the centre line of an
    /// opening `width` wide, at arc length `s` of line `line`.
    pub fn darkness(&self, line: usize, s: f64, x: f64, width: f64) -> f64 {
        let half = width / 2.0;
        if half <= 0.0 {
            return 0.0;
        }
        let x = x.abs();
        if x < half {
            let slot = Self::slot(width);
            let depth = self.depth * (0.75 + 0.25 * self.along(line, s, 2));
            let depth = depth + (SLOT_DEPTH - depth) * slot;
            let dirty = self.varying(line, s, 3, DIRT_M) < self.dirt;
            let depth = if dirty { depth / 3.0 } else { depth };
            let ramp = self.ramp(width);
            return if half - x >= ramp {
                depth
            } else {
                depth * (half - x) / ramp
            };
        }
        let shoulder = self.spall * half * (0.5 + self.along(line, s, 4));
        if x < half + shoulder {
            self.spall_depth * (1.0 - (x - half) / shoulder)
        } else {
            0.0
        }
    }

    /// The darkness summed across the crack from `lo` to `hi` metres
    /// across its centre line (metre-shares of light), exactly: the
    /// section is straight between its corners, so one midpoint each
    /// stretch between them sums it.
    pub fn across(&self, line: usize, s: f64, lo: f64, hi: f64, width: f64) -> f64 {
        let half = width / 2.0;
        let shoulder = self.spall * half * (0.5 + self.along(line, s, 4));
        let ramp = self.ramp(width);
        let mut corners = vec![lo, hi];
        for c in [half + shoulder, half, half - ramp] {
            corners.extend([-c, c]);
        }
        corners.retain(|c| (lo..=hi).contains(c));
        corners.sort_by(f64::total_cmp);
        corners
            .windows(2)
            .map(|w| (w[1] - w[0]) * self.darkness(line, s, (w[0] + w[1]) / 2.0, width))
            .sum()
    }

    /// How much of a slot an opening `width` wide is: all of one as the
    /// width goes to nothing, half at [`SLOT_M`], less as its square grows.
    fn slot(width: f64) -> f64 {
        1.0 / (1.0 + (width / SLOT_M).powi(2))
    }

    /// How far in from each edge the interior ramps to its full depth,
    /// metres: the section's V, less as the opening narrows to a slot.
    fn ramp(&self, width: f64) -> f64 {
        self.vee * (1.0 - Self::slot(width)) * width / 2.0
    }

    /// How far the darkness reaches from the centre line, metres, for an
    /// opening `width` wide at its widest.
    pub fn reach(&self, width: f64) -> f64 {
        width / 2.0 * (1.0 + 1.5 * self.spall)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sections_range_from_u_to_v_with_spalls_and_dirt() {
        let sections: Vec<Section> = (0..200).map(Section::of).collect();
        assert!(sections.iter().any(|s| s.vee < 0.2) && sections.iter().any(|s| s.vee > 0.8));
        assert!(sections.iter().any(|s| s.spall > 0.5));
        assert_eq!(Section::of(7), Section::of(7));
        let s = Section::of(3);
        let w = 0.004;
        // Darkest inside, a shoulder at most outside, nothing far off.
        let inside = s.darkness(0, 0.1, 0.0, w);
        assert!(inside > 0.1 && inside <= SLOT_DEPTH);
        assert!(s.darkness(0, 0.1, w / 2.0 + 1e-6, w) <= s.spall_depth);
        assert_eq!(s.darkness(0, 0.1, s.reach(w) * 1.5 + 0.01, w), 0.0);
        // The opening varies along the crack within its raggedness.
        let factors: Vec<f64> = (0..100)
            .map(|k| s.opening(0, f64::from(k) * 0.005))
            .collect();
        assert!(
            factors
                .iter()
                .all(|f| *f <= 1.0 && *f >= 1.0 - s.ragged - 1e-12)
        );
    }

    #[test]
    fn narrower_openings_hold_more_darkness_for_their_width() {
        // Summed across the opening, over its width: its mean darkness.
        let mean = |s: &Section, w: f64| s.across(0, 0.1, -w / 2.0, w / 2.0, w) / w;
        for id in 0..50 {
            let s = Section::of(id);
            let (slot, crack, wide) = (mean(&s, 0.0005), mean(&s, 0.002), mean(&s, 0.008));
            assert!(slot > crack && crack > wide, "{id}: {slot} {crack} {wide}");
            // A slot is nearly as dark as a slot can be, unless dirt fills it.
            assert!(
                !(SLOT_DEPTH / 2.5..=0.8 * SLOT_DEPTH).contains(&slot),
                "{id}: {slot}"
            );
        }
    }
}
