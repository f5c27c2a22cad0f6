//! The widths of a flight's views, once every crack of it has been
//! crossed: what they are read against is the flight's (the contrast of a
//! crack's interior, the camera's blur), then each view's width.

use std::collections::BTreeMap;

use postflight_core::outputs::localise::FlightWidths;
use rayon::prelude::*;

use crate::blur::Blur;
use crate::contrast::{self, Contrast};
use crate::observation::{Crossed, Observation};
use crate::settings::LocaliseConfig;

/// Each view's width, once every crack of the flight has been crossed:
/// its darkness over the contrast its own resolved stretches show, else
/// the other cracks of its photo, else the flight's, else the setting's;
/// its walls as the camera's blur spreads them (the flight's thin lines'
/// or crack walls' blur, else the setting's, else unknown).
pub fn measure(observations: &mut [Observation], settings: &LocaliseConfig) -> FlightWidths {
    fn crossed(o: &Observation) -> Option<&Crossed> {
        o.placement.as_ref()?.crossed.as_ref()
    }
    let given = settings.crack_darkness;
    // Each view's own interior, read once: its photo's and the flight's
    // are made of them.
    let own: Vec<Option<f64>> = observations
        .iter()
        .map(|o| crossed(o).and_then(|c| contrast::interior(&c.crossings)))
        .collect();
    let mut by_photo: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
    for (o, i) in observations.iter().zip(&own) {
        if let Some(i) = i {
            by_photo.entry(o.detection.frame).or_default().push(*i);
        }
    }
    let flight: Vec<f64> = by_photo.values().flatten().copied().collect();
    let flight_contrast = Contrast::nearest(None, &[], &flight, given);
    let blur = Blur::of(
        observations
            .iter()
            .filter_map(crossed)
            .flat_map(|c| c.crossings.iter().flatten()),
        flight_contrast.share,
        settings.camera_blur_px,
    );
    observations.par_iter_mut().zip(own).for_each(|(o, own)| {
        let photo = by_photo
            .get(&o.detection.frame)
            .map_or(&[][..], Vec::as_slice);
        if let Some(p) = o.placement.as_mut()
            && let Some(crossed) = p.crossed.take()
        {
            let contrast = Contrast::nearest(own, photo, &flight, given);
            p.width = crossed.width(&contrast, &blur);
        }
    });
    FlightWidths {
        interior_darkness: flight_contrast.share,
        contrast_from: flight_contrast.from,
        resolved_cracks: flight.len(),
        blur_px: blur.sigma_px,
        blur_uncertainty_px: blur.uncertainty_px,
        blur_from: blur.from,
        blur_samples: blur.samples,
    }
}
