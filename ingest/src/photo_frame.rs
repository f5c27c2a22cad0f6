//! Where a flight's photo folders are posed: the east-north-up frame's
//! origin (as set, else the first photo's) and the reconstruction placed in
//! it (by its reference, else fitted to the photos' GPS).

use std::collections::BTreeMap;

use postflight_core::geo::GeoOrigin;

use crate::error::IngestError;
use crate::reconstruction::{Placed, Reconstruction};
use crate::source::Source;
use crate::stage::{IngestOptions, Progress};

/// The east-north-up frame photo folders are posed in: as set, else at the
/// first photo of the first photo folder; none without photo folders.
pub(crate) fn photo_origin(
    options: &IngestOptions,
    sources: &[Source],
) -> Result<Option<GeoOrigin>, IngestError> {
    let mut folders = sources.iter().filter_map(|s| match s {
        Source::Photos(folder) => Some(folder),
        Source::Recording(_) => None,
    });
    let Some(first) = folders.next() else {
        return Ok(None);
    };
    if let Some(origin) = options.settings.photo_origin {
        return Ok(Some(origin));
    }
    let position = first
        .first_position()
        .map_err(|why| IngestError::NoPosedPhotos {
            path: first.path().to_owned(),
            first: Some(why),
        })?;
    Ok(Some(GeoOrigin {
        position,
        yaw_deg: 0.0,
    }))
}

/// Where the run's photo folders are posed.
pub(crate) struct PhotoFrame<'a> {
    /// The east-north-up frame's origin.
    pub(crate) origin: &'a GeoOrigin,
    pub(crate) reconstruction: Option<&'a Placed>,
}

/// The reconstruction the settings give, read and placed in the photos'
/// frame (by its reference, else fitted to every photo folder's GPS).
pub(crate) fn reconstruction(
    options: &IngestOptions,
    sources: &[Source],
    origin: Option<&GeoOrigin>,
    progress: &mut dyn Progress,
) -> Result<Option<Placed>, IngestError> {
    let Some(path) = &options.settings.reconstruction else {
        return Ok(None);
    };
    let unusable = |why: String| IngestError::Reconstruction {
        path: path.clone(),
        why,
    };
    let origin = origin.ok_or_else(|| {
        unusable(
            "it poses photos, and the flight has no photo folder; give the photos with --photos"
                .into(),
        )
    })?;
    let reconstruction = Reconstruction::load(path).map_err(unusable)?;
    let mut positions = BTreeMap::new();
    for source in sources {
        if let Source::Photos(folder) = source {
            positions.extend(folder.positions(origin, progress));
        }
    }
    reconstruction
        .place(origin, &positions)
        .map(Some)
        .map_err(unusable)
}
