//! The contrast between the surface and a crack's interior, which a crack
//! thinner than the camera's blur never shows: its darkness summed across
//! it is divided by it. It is read where cracks resolve (a flat bottom at
//! least [`RESOLVED_PX`](crate::crossing::RESOLVED_PX) wide, whose depth is
//! its interior's): the crack's own resolved stretches, else the other
//! cracks of the same photo, else the flight's, else the setting
//! (`[localise] crack_darkness`). A crack's interior is dark because its
//! bottom is out of the light, so cracks under one light share it: on the
//! crack-width gauge readings' two sites (docs/evaluation.md) the flights'
//! resolved cracks lack 0.90 and 0.92 of the surface's brightness, and the
//! thin ones' darkness summed over that reads their gauge widths.

use postflight_core::outputs::localise::ContrastSource;

use crate::crossing::Crossing;
use crate::stats::{median, robust_sigma};

/// A crack has resolved stretches when this share of its crossings (and
/// [`MIN_RESOLVED`] at least) are resolved.
const MIN_RESOLVED_SHARE: f64 = 0.1;
/// Fewest resolved crossings of a crack that say its interior.
const MIN_RESOLVED: usize = 5;
/// How far one crack's interior may differ from another's under the same
/// light, as a share of it (one standard deviation), where too few cracks
/// resolve to say: the flat-bottomed profiles of the gauge readings' two
/// sites scatter by 2 and 5% about their medians; an unknown flight's
/// setting is further off.
const GIVEN_SPREAD: f64 = 0.08;
/// Resolved cracks that say how far one crack's interior differs from
/// another's.
const MIN_CRACKS_FOR_SPREAD: usize = 3;
/// Fewest resolved cracks that say the interior of a photo's or a flight's
/// other cracks: one or two resolved stretches in a flight of hairlines
/// are as often something else (a shadowed edge, a stain) and would scale
/// every hairline's width by their lighter insides.
const MIN_CRACKS: usize = 3;

/// The contrast a darkness width divides by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contrast {
    /// The share of the surface's brightness a crack's interior lacks.
    pub share: f64,
    /// Where it was read.
    pub from: ContrastSource,
    /// How far off `share` may be for another crack, as a share of it (one
    /// standard deviation).
    pub spread: f64,
}

impl Contrast {
    /// The setting's contrast.
    pub fn given(share: f64) -> Self {
        Self {
            share,
            from: ContrastSource::Setting,
            spread: GIVEN_SPREAD,
        }
    }

    /// The contrast of cracks with these interiors ([`interior`]), read
    /// from `from`: their median, scattered as they are.
    pub fn of(interiors: &[f64], from: ContrastSource) -> Option<Self> {
        let share = median(interiors.to_vec())?;
        let spread = if interiors.len() >= MIN_CRACKS_FOR_SPREAD && share > 0.0 {
            robust_sigma(interiors.iter().map(|i| (i - share).abs()).collect())? / share
        } else {
            GIVEN_SPREAD
        };
        Some(Self {
            share,
            from,
            spread,
        })
    }

    /// The nearest that was read: the crack's own, the photo's, the
    /// flight's (each of [`MIN_CRACKS`] cracks at least), else the
    /// setting's.
    pub fn nearest(crack: Option<f64>, photo: &[f64], flight: &[f64], given: f64) -> Self {
        let enough = |cracks: &[f64]| cracks.len() >= MIN_CRACKS;
        crack
            .and_then(|i| Self::of(&[i], ContrastSource::Crack))
            .or_else(|| enough(photo).then(|| Self::of(photo, ContrastSource::Photo))?)
            .or_else(|| enough(flight).then(|| Self::of(flight, ContrastSource::Flight))?)
            .unwrap_or_else(|| Self::given(given))
    }
}

/// A crack's interior, as the share of the surface's brightness it lacks,
/// where the crack shows it: the median over its resolved crossings, if
/// it has stretches of them. A few scattered crossings that look resolved
/// are something else (a bend the profile runs along, a crossing of two
/// cracks) and would scale every thin point's width by a wrong darkness.
pub fn interior(crossings: &[Option<Crossing>]) -> Option<f64> {
    let measured = crossings.iter().flatten().count();
    let resolved: Vec<f64> = crossings
        .iter()
        .flatten()
        .filter_map(Crossing::interior)
        .collect();
    stretches(resolved.len(), measured)
        .then(|| median(resolved))
        .flatten()
}

/// Whether `n` of a crack's `measured` crossings make stretches of it.
fn stretches(n: usize, measured: usize) -> bool {
    n as f64 >= (MIN_RESOLVED_SHARE * measured as f64).max(MIN_RESOLVED as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_contrast_read_is_taken() {
        let crack = Contrast::nearest(Some(0.9), &[0.8], &[0.7], 0.85);
        assert_eq!((crack.share, crack.from), (0.9, ContrastSource::Crack));
        let photo = Contrast::nearest(None, &[0.8, 0.82, 0.9], &[0.7], 0.85);
        assert_eq!((photo.share, photo.from), (0.82, ContrastSource::Photo));
        // Three cracks scatter by a robust sigma of 0.02 about 0.82.
        assert!((photo.spread - 1.4826 * 0.02 / 0.82).abs() < 1e-9);
        let flight = Contrast::nearest(None, &[0.6], &[0.7, 0.72, 0.74], 0.85);
        assert_eq!((flight.share, flight.from), (0.72, ContrastSource::Flight));
        // Two resolved cracks in a flight say nothing of the others.
        let few = Contrast::nearest(None, &[0.2], &[0.2, 0.3], 0.85);
        assert_eq!((few.share, few.from), (0.85, ContrastSource::Setting));
        let given = Contrast::nearest(None, &[], &[], 0.85);
        assert_eq!((given.share, given.from), (0.85, ContrastSource::Setting));
    }
}
