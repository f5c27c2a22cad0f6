//! Photo folders as flights: the geotagged JPEGs a DJI enterprise drone
//! (or any camera that tags GPS) leaves on its card, one folder per
//! sortie. Each photo is posed from its tags ([`tags`]): its GPS position
//! and DJI's gimbal angles, in the east-north-up frame at the run's geo
//! origin ([`pose`]); its lens from DJI's calibration or EXIF's focal
//! length; its accuracy from DJI's RTK tags. The photos' positions are
//! also the recording's GPS fixes, and the drone's tagged speed gives the
//! motion blur.

mod pose;
mod tags;
mod xmp;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::DynamicImage;
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};
use postflight_core::frame::{Compression, ImageEncoding};
use postflight_core::geo::{GeoOrigin, Geodetic};
use postflight_core::outputs::ingest::{
    GnssFix, PhotoFolderSummary, PoseSource, RecordingSummary, SkippedPhoto,
};
use postflight_core::pose::StampedPose;
use postflight_core::{
    Camera, Frame, ImageLocation, ImageStatus, Intrinsics, PoseStatus, Trajectory,
};
use rayon::prelude::*;

use crate::error::IngestError;
use crate::ingested::Ingested;
use crate::reconstruction::Placed;
use crate::stage::Progress;
use tags::{LensSource, PhotoTags};

/// The body frame photo folders are posed as: the camera's gimbal.
const GIMBAL: &str = "gimbal";
/// What the photos' poses are said to come from: their tags, or a
/// reconstruction.
const POSE_SOURCE: &str = "photo tags (EXIF GPS, XMP drone-dji gimbal angles)";
const RECONSTRUCTED: &str = "the reconstruction (photo tags where it has no image)";
/// What the photos' GPS fixes are said to come from.
const FIX_SOURCE: &str = "photo EXIF GPS";
/// Half the span of the poses added either side of a photo along the
/// drone's tagged velocity, for its motion blur, seconds (within the
/// blur's velocity fit, shorter than any interval between photos).
const VELOCITY_STEP_S: f64 = 0.05;
/// The camera's optical frame on its gimbal (x forward, y left, z up, as
/// ROS bodies are): the camera's mounting, so that plan viewpoints (a body
/// pose and a gimbal pitch) are judged and planned as shots of it.
fn optical_on_gimbal() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_quaternion(Quaternion::new(0.5, -0.5, 0.5, -0.5)),
    )
}

/// Photos read between progress reports.
const PROGRESS_BATCH: usize = 32;
/// NavSatFix statuses the photos' positions are recorded with.
const FIX: i8 = 0;
const FIX_RTK: i8 = 2;

/// A folder of photos, listed.
pub struct PhotoFolder {
    path: PathBuf,
    /// Its JPEGs' file names, in name order.
    photos: Vec<String>,
    size_bytes: u64,
    /// Every photo's tags, once read.
    tags: OnceLock<Vec<Result<PhotoTags, String>>>,
}

/// Read a JPEG's tags as ingest does, keeping only whether they read: the
/// `photo_tags` fuzz target's entry (`fuzz/`).
#[doc(hidden)]
pub fn read_tags(jpeg: &[u8]) -> Result<(), String> {
    tags::read(jpeg).map(|_| ())
}

impl PhotoFolder {
    /// Whether a file is named as a JPEG photo.
    pub fn is_photo_name(path: &Path) -> bool {
        let extension = path.extension().and_then(|e| e.to_str());
        extension.is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("jpeg"))
    }

    /// Whether a directory holds photos.
    pub fn holds_photos(dir: &Path) -> bool {
        std::fs::read_dir(dir).is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.path().is_file() && Self::is_photo_name(&e.path()))
        })
    }

    /// List the JPEGs of `dir`; an error when it holds none.
    pub fn open(dir: &Path) -> Result<Self, IngestError> {
        let listed = std::fs::read_dir(dir).map_err(|cause| postflight_core::Error::Open {
            path: dir.to_owned(),
            cause,
        })?;
        let mut photos = Vec::new();
        let mut size_bytes = 0;
        for entry in listed.flatten() {
            let path = entry.path();
            if path.is_file() && Self::is_photo_name(&path) {
                size_bytes += entry.metadata().map_or(0, |m| m.len());
                photos.push(entry.file_name().to_string_lossy().into_owned());
            }
        }
        if photos.is_empty() {
            return Err(IngestError::NoRecordingsIn {
                path: dir.to_owned(),
            });
        }
        photos.sort();
        Ok(Self {
            path: dir.to_owned(),
            photos,
            size_bytes,
            tags: OnceLock::new(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The photos' bytes together.
    pub fn len(&self) -> u64 {
        self.size_bytes
    }

    pub fn is_empty(&self) -> bool {
        self.photos.is_empty()
    }

    /// A photo's bytes, as the camera wrote them.
    pub fn photo(&self, name: &str) -> Result<Vec<u8>, IngestError> {
        let path = self.path.join(name);
        postflight_core::user_file::read(&path)
            .map_err(|cause| postflight_core::Error::Open { path, cause }.into())
    }

    /// A photo, decoded.
    pub fn image(&self, name: &str) -> Result<DynamicImage, IngestError> {
        let bytes = self.photo(name)?;
        crate::image::decode_compressed(&bytes).map_err(|why| IngestError::PhotoUnreadable {
            path: self.path.join(name),
            why,
        })
    }

    /// The position of its first photo (by name) that has one: the run's
    /// geo origin when none is given. Without one, why: the first photo's
    /// error where a photo has one, else that none is tagged.
    pub fn first_position(&self) -> Result<Geodetic, String> {
        let mut first_error = None;
        for name in &self.photos {
            let tags = self
                .photo(name)
                .map_err(|e| e.to_string())
                .and_then(|bytes| tags::read(&bytes).map_err(|why| format!("{name}: {why}")));
            match tags {
                Ok(tags::PhotoTags {
                    position: Some(at), ..
                }) => return Ok(at),
                Ok(_) => {}
                Err(why) => {
                    first_error.get_or_insert(why);
                }
            }
        }
        Err(first_error.unwrap_or_else(|| "no photo has an EXIF GPS position".into()))
    }

    /// The photos' GPS positions in the map frame at `origin`, by name.
    pub(crate) fn positions(
        &self,
        origin: &GeoOrigin,
        progress: &mut dyn Progress,
    ) -> BTreeMap<String, Point3<f64>> {
        let tags = self.tags(progress).iter();
        let positions = self.photos.iter().zip(tags).filter_map(|(name, t)| {
            let at = t.as_ref().ok()?.position?;
            Some((name.clone(), origin.to_local(&at)))
        });
        positions.collect()
    }

    /// Every photo posed in the east-north-up frame at `origin` (by the
    /// reconstruction where it registered the photo, else by its tags);
    /// photos that cannot be posed are skipped with a warning each, or
    /// refused when `strict`.
    pub(crate) fn ingest(
        &self,
        index: u16,
        origin: &GeoOrigin,
        reconstruction: Option<&Placed>,
        strict: bool,
        progress: &mut dyn Progress,
    ) -> Result<Ingested, IngestError> {
        let tagged = self.tags(progress);
        let mut posed = Vec::new();
        let mut skipped = Vec::new();
        for (name, tags) in self.photos.iter().zip(tagged) {
            let registered = reconstruction.and_then(|r| r.image(name));
            let tags = tags.clone();
            match tags.and_then(|t| Posed::new(name, t, origin, registered)) {
                Ok(p) => posed.push(p),
                Err(why) if strict => {
                    return Err(IngestError::UnusablePhoto {
                        path: self.path.join(name),
                        why,
                    });
                }
                Err(why) => skipped.push(SkippedPhoto {
                    photo: name.clone(),
                    why,
                }),
            }
        }
        if posed.is_empty() {
            return Err(IngestError::NoPosedPhotos {
                path: self.path.clone(),
                first: skipped.first().map(|s| format!("{}: {}", s.photo, s.why)),
            });
        }
        posed.sort_by_key(|p| (p.time_ns, p.name.clone()));
        Ok(self.ingested(index, posed, skipped, origin))
    }

    /// Every photo's tags, read once.
    fn tags(&self, progress: &mut dyn Progress) -> &[Result<PhotoTags, String>] {
        if let Some(tags) = self.tags.get() {
            progress.bytes(self.size_bytes, self.size_bytes);
            return tags;
        }
        let tags = self.read_tags(progress);
        self.tags.get_or_init(|| tags)
    }

    /// Every photo's tags, read in parallel a batch at a time.
    fn read_tags(&self, progress: &mut dyn Progress) -> Vec<Result<PhotoTags, String>> {
        let mut tags = Vec::with_capacity(self.photos.len());
        let mut done = 0;
        for batch in self.photos.chunks(PROGRESS_BATCH) {
            let read: Vec<(u64, Result<PhotoTags, String>)> = batch
                .par_iter()
                .map(|name| match self.photo(name) {
                    Ok(bytes) => (bytes.len() as u64, tags::read(&bytes)),
                    Err(e) => (0, Err(e.to_string())),
                })
                .collect();
            for (bytes, t) in read {
                done += bytes;
                tags.push(t);
            }
            progress.bytes(done, self.size_bytes);
        }
        tags
    }

    /// The posed photos as a recording: frames, the camera's path, cameras,
    /// fixes and the summary.
    fn ingested(
        &self,
        index: u16,
        posed: Vec<Posed>,
        skipped: Vec<SkippedPhoto>,
        origin: &GeoOrigin,
    ) -> Ingested {
        let cameras = cameras_of(index, &posed);
        let mut warnings: Vec<String> = skipped
            .iter()
            .map(|s| {
                format!(
                    "{}: {}; skipped ({} refuses it)",
                    s.photo,
                    s.why,
                    crate::settings::keys::strict
                )
            })
            .collect();
        let no_offset = posed.iter().filter(|p| !p.time_has_offset).count();
        if no_offset > 0 {
            warnings.push(format!(
                "{no_offset} photos do not say their UTC offset (EXIF OffsetTimeOriginal); their times are read as UTC"
            ));
        }
        let frames: Vec<Frame> = posed
            .iter()
            .map(|p| p.frame(index, &cameras[&p.lens_key()].topic))
            .collect();
        let fixes = posed.iter().filter_map(|p| p.fix(index)).collect();
        let trajectory = path_of(&posed);
        let (start, end) = (posed[0].time_ns, posed[posed.len() - 1].time_ns);
        let summary = RecordingSummary {
            path: std::path::absolute(&self.path).unwrap_or_else(|_| self.path.clone()),
            size_bytes: self.size_bytes,
            messages: BTreeMap::new(),
            frames: frames.len() as u64,
            poses: posed.len() as u64,
            pose_source: PoseSource::of(&trajectory),
            start_time_ns: start,
            end_time_ns: end,
            truncated: false,
            truncated_at_byte: None,
            corrupt_chunks: 0,
            map: None,
            placement: Default::default(),
            reused: false,
            photos: Some(PhotoFolderSummary {
                photos: self.photos.len() as u64,
                rtk_fixed: posed
                    .iter()
                    .filter(|p| p.tags.rtk.is_some_and(|r| r.fixed()))
                    .count() as u64,
                reconstructed: posed.iter().filter(|p| p.reconstructed).count() as u64,
                skipped,
                origin: *origin,
            }),
        };
        Ingested {
            summary,
            frames,
            trajectory,
            cameras: cameras.into_values().collect(),
            fixes,
            warnings,
        }
    }
}

/// A photo with everything a pose needs.
struct Posed {
    name: String,
    time_ns: i64,
    time_has_offset: bool,
    /// Its GPS position (none where a reconstruction posed it without).
    position: Option<Geodetic>,
    camera_pose: Isometry3<f64>,
    lens: (Intrinsics, LensSource),
    /// The drone's velocity in the map frame, metres per second.
    velocity: Option<nalgebra::Vector3<f64>>,
    /// Posed by a reconstruction, not by its tags.
    reconstructed: bool,
    tags: PhotoTags,
}

impl Posed {
    /// The photo posed at `origin`: by the reconstruction's image of it
    /// (its lens and pose in the map frame) where there is one, else by its
    /// tags; or why it cannot be.
    fn new(
        name: &str,
        tags: PhotoTags,
        origin: &GeoOrigin,
        registered: Option<(Intrinsics, Isometry3<f64>)>,
    ) -> Result<Self, String> {
        let (time_ns, time_has_offset) =
            tags.time.ok_or("no capture time (EXIF DateTimeOriginal)")?;
        let position = tags.position;
        let velocity = tags
            .velocity_ned
            .zip(position)
            .map(|(v, at)| pose::velocity(origin, &at, &v));
        let (camera_pose, lens, reconstructed) = match registered {
            Some((lens, camera)) => (camera, (lens, LensSource::Reconstruction), true),
            None => {
                let at = position
                    .ok_or("no GPS position (EXIF GPSLatitude, GPSLongitude and an altitude)")?;
                let gimbal = tags
                    .gimbal
                    .ok_or("no camera orientation (XMP drone-dji:GimbalYawDegree and GimbalPitchDegree); pose it from a reconstruction")?;
                let lens = tags.lens.clone().ok_or(
                    "no focal length (XMP drone-dji:DewarpData or CalibratedFocalLength, EXIF FocalLength with FocalPlaneXResolution, or FocalLengthIn35mmFilm)",
                )?;
                (pose::camera_pose(origin, &at, &gimbal), lens, false)
            }
        };
        Ok(Self {
            name: name.to_string(),
            time_ns,
            time_has_offset,
            position,
            camera_pose,
            velocity,
            lens,
            reconstructed,
            tags,
        })
    }

    /// What tells its camera from another's: the camera's name and lens.
    fn lens_key(&self) -> String {
        let k = &self.lens.0;
        format!(
            "{}|{}x{}|{:?}",
            self.tags.camera,
            k.width,
            k.height,
            (k.fx, k.fy, k.cx, k.cy, &k.distortion)
        )
    }

    fn frame(&self, recording: u16, camera: &str) -> Frame {
        Frame {
            index: 0,
            recording,
            time_ns: self.time_ns,
            log_time_ns: self.time_ns,
            topic: camera.to_string(),
            frame_id: camera.to_string(),
            width: Some(self.tags.width),
            height: Some(self.tags.height),
            encoding: ImageEncoding::Compressed(Compression::Jpeg),
            camera_pose: Some(self.camera_pose),
            pose_status: PoseStatus::Ok,
            image_status: ImageStatus::Ok,
            location: ImageLocation::Photo(self.name.clone()),
            exposure_s: self.tags.exposure_s,
            position_std_m: self
                .tags
                .rtk
                .and_then(|r| r.std_m)
                .map(|[e, n, u]| (e * e + n * n + u * u).sqrt()),
        }
    }

    fn fix(&self, recording: u16) -> Option<GnssFix> {
        Some(GnssFix {
            recording,
            time_ns: self.time_ns,
            topic: FIX_SOURCE.to_string(),
            position: self.position?,
            status: match self.tags.rtk.is_some_and(|r| r.fixed()) {
                true => FIX_RTK,
                false => FIX,
            },
        })
    }
}

/// The photos' cameras, one per camera name and lens, by [`Posed::lens_key`];
/// each named by its camera (and focal length, where one camera has
/// several lenses or zooms).
fn cameras_of(recording: u16, posed: &[Posed]) -> BTreeMap<String, Camera> {
    let mut lenses: BTreeMap<String, &Posed> = BTreeMap::new();
    for p in posed {
        lenses.entry(p.lens_key()).or_insert(p);
    }
    let mut per_name: BTreeMap<&str, usize> = BTreeMap::new();
    for p in lenses.values() {
        *per_name.entry(&p.tags.camera).or_default() += 1;
    }
    lenses
        .iter()
        .map(|(key, p)| {
            let name = match p.tags.camera.as_str() {
                "" => "camera",
                name => name,
            };
            let topic = match per_name[p.tags.camera.as_str()] {
                1 => name.to_string(),
                _ => format!("{name} {:.0} px", p.lens.0.fx),
            };
            let camera = Camera {
                recording,
                topic: topic.clone(),
                frame_id: topic,
                intrinsics: Some(p.lens.0.clone()),
                intrinsics_source: Some(p.lens.1.describe().to_string()),
                extrinsic: Some(optical_on_gimbal()),
                body_frame: GIMBAL.to_string(),
            };
            (key.clone(), camera)
        })
        .collect()
}

/// The gimbal's path: a pose per photo, and where the drone's velocity is
/// tagged, one either side along it (what the blur's velocity fit reads).
fn path_of(posed: &[Posed]) -> Trajectory {
    let step_ns = (VELOCITY_STEP_S * 1e9) as i64;
    let optical_gimbal = optical_on_gimbal().inverse();
    let mut poses = Vec::new();
    for p in posed {
        let gimbal = p.camera_pose * optical_gimbal;
        poses.push(StampedPose {
            time_ns: p.time_ns,
            pose: gimbal,
        });
        if let Some(v) = p.velocity {
            for sign in [-1.0, 1.0] {
                let shift = Translation3::from(v * VELOCITY_STEP_S * sign);
                poses.push(StampedPose {
                    time_ns: p.time_ns + (sign as i64) * step_ns,
                    pose: shift * gimbal,
                });
            }
        }
    }
    poses.sort_by_key(|p| p.time_ns);
    poses.dedup_by_key(|p| p.time_ns);
    let source = match posed.iter().any(|p| p.reconstructed) {
        true => RECONSTRUCTED,
        false => POSE_SOURCE,
    };
    Trajectory::new(
        "enu".to_string(),
        GIMBAL.to_string(),
        source.to_string(),
        poses,
    )
}
