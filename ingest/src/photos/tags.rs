//! What a photo's tags say: when it was taken, where, which way the camera
//! looked, through what lens, how fast the drone flew and how well its
//! position is known. EXIF (through `kamadak-exif`) for time, GPS, exposure
//! and focal length; DJI's XMP (`drone-dji:`) for the gimbal, the
//! calibrated lens, the absolute altitude, speed and RTK.

use std::collections::BTreeMap;
use std::io::Cursor;

use exif::{Exif, In, Tag, Value};
use nalgebra::Vector3;
use postflight_core::geo::Geodetic;
use postflight_core::shown::Shown;
use postflight_core::{Distortion, Intrinsics};

use super::xmp;

/// The diagonal of a 35 mm film frame (36 x 24 mm), millimetres.
const FILM_DIAGONAL_MM: f64 = 43.266_615_305_567_87;

/// Where a photo's lens model came from, best first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LensSource {
    /// A photogrammetry reconstruction's refined camera.
    Reconstruction,
    /// DJI's `DewarpData`: focal lengths, principal point and distortion.
    DewarpData,
    /// DJI's `CalibratedFocalLength` and `CalibratedOpticalCenterX/Y`.
    CalibratedFocalLength,
    /// EXIF `FocalLength` over the sensor's `FocalPlaneXResolution`.
    FocalPlane,
    /// EXIF `FocalLengthIn35mmFilm`, scaled by the image diagonal.
    FilmEquivalent,
}

impl LensSource {
    /// How `cameras.json` names it.
    pub(crate) fn describe(self) -> &'static str {
        match self {
            Self::Reconstruction => "the reconstruction's refined camera",
            Self::DewarpData => "the photos' XMP drone-dji:DewarpData",
            Self::CalibratedFocalLength => "the photos' XMP drone-dji:CalibratedFocalLength",
            Self::FocalPlane => "the photos' EXIF FocalLength and FocalPlaneXResolution",
            Self::FilmEquivalent => "the photos' EXIF FocalLengthIn35mmFilm",
        }
    }
}

/// A camera's (or gimbal's) attitude as DJI tags it: yaw clockwise from
/// true north, pitch up from the horizon (-90 looks straight down), roll;
/// degrees, applied in that order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Attitude {
    pub(crate) yaw_deg: f64,
    pub(crate) pitch_deg: f64,
    pub(crate) roll_deg: f64,
}

/// The RTK solution a photo was positioned with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rtk {
    /// DJI's `RtkFlag`: 50 fixed, 34 float, 16 single point, 0 none.
    pub(crate) flag: u32,
    /// One standard deviation east-west, north-south and up, metres.
    pub(crate) std_m: Option<[f64; 3]>,
}

impl Rtk {
    /// A fixed solution (centimetres).
    pub(crate) fn fixed(&self) -> bool {
        self.flag == 50
    }
}

/// A photo's tags, as far as it has them.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PhotoTags {
    /// `Make Model`, as the camera names itself.
    pub(crate) camera: String,
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// Capture time, ns since the Unix epoch, and whether the photo said
    /// its UTC offset (else the time is read as UTC).
    pub(crate) time: Option<(i64, bool)>,
    /// WGS 84 latitude and longitude; the altitude DJI's
    /// `AbsoluteAltitude` gives (above the ellipsoid), else EXIF's.
    pub(crate) position: Option<Geodetic>,
    pub(crate) gimbal: Option<Attitude>,
    pub(crate) lens: Option<(Intrinsics, LensSource)>,
    pub(crate) exposure_s: Option<f64>,
    /// The drone's velocity, north-east-down, metres per second.
    pub(crate) velocity_ned: Option<Vector3<f64>>,
    pub(crate) rtk: Option<Rtk>,
}

/// Read a JPEG's tags; an error when it is not a readable JPEG.
pub(crate) fn read(jpeg: &[u8]) -> Result<PhotoTags, String> {
    let (width, height) = image_size(jpeg)?;
    // A copy cut short still has its header: caught here, not when detect
    // decodes it.
    if !crate::image::ends_with_eoi(jpeg) {
        return Err("it is truncated (it does not end with JPEG's end-of-image marker)".into());
    }
    let exif = match exif::Reader::new().read_from_container(&mut Cursor::new(jpeg)) {
        Ok(exif) => Some(exif),
        Err(exif::Error::NotFound(_)) => None,
        Err(e) => return Err(format!("its EXIF cannot be read ({e})")),
    };
    let dji = match xmp::packet(jpeg) {
        Some(packet) => xmp::drone_dji(packet)?,
        None => BTreeMap::new(),
    };
    let exif = exif.as_ref();
    let number = |name: &str| dji.get(name).and_then(|v| v.parse::<f64>().ok());
    Ok(PhotoTags {
        camera: exif.map(camera_name).unwrap_or_default(),
        width,
        height,
        time: exif.and_then(capture_time),
        position: match exif {
            Some(e) => position(e, number("AbsoluteAltitude"))?,
            None => None,
        },
        gimbal: gimbal(&dji)?,
        lens: lens(&dji, exif, width, height)?,
        exposure_s: exif
            .and_then(|e| rational(e, Tag::ExposureTime))
            .filter(|s| *s > 0.0),
        velocity_ned: match (
            number("FlightXSpeed"),
            number("FlightYSpeed"),
            number("FlightZSpeed"),
        ) {
            (Some(n), Some(e), d) => Some(Vector3::new(n, e, d.unwrap_or(0.0))),
            _ => None,
        },
        rtk: number("RtkFlag").map(|flag| Rtk {
            flag: flag as u32,
            std_m: match (
                number("RtkStdLon"),
                number("RtkStdLat"),
                number("RtkStdHgt"),
            ) {
                (Some(e), Some(n), Some(u)) => Some([e, n, u]),
                _ => None,
            },
        }),
    })
}

/// The gimbal's attitude (roll 0 where only yaw and pitch are tagged);
/// an error where its angles are tagged but are not angles.
fn gimbal(dji: &BTreeMap<String, String>) -> Result<Option<Attitude>, String> {
    let number = |name: &str| dji.get(name).and_then(|v| v.parse::<f64>().ok());
    let (Some(yaw_deg), Some(pitch_deg)) = (number("GimbalYawDegree"), number("GimbalPitchDegree"))
    else {
        return Ok(None);
    };
    let roll_deg = number("GimbalRollDegree").unwrap_or(0.0);
    // Within a turn or two of zero: DJI tags ±180 at most.
    if ![yaw_deg, pitch_deg, roll_deg]
        .iter()
        .all(|v| v.abs() <= 720.0)
    {
        return Err(format!(
            "its gimbal angles (yaw {}, pitch {}, roll {}) are not angles in degrees",
            Shown(yaw_deg),
            Shown(pitch_deg),
            Shown(roll_deg)
        ));
    }
    Ok(Some(Attitude {
        yaw_deg,
        pitch_deg,
        roll_deg,
    }))
}

/// Width and height from the JPEG's frame header.
fn image_size(jpeg: &[u8]) -> Result<(u32, u32), String> {
    let reader = image::ImageReader::with_format(Cursor::new(jpeg), image::ImageFormat::Jpeg);
    reader
        .into_dimensions()
        .map_err(|e| format!("it is not a readable JPEG ({})", crate::image::one_line(e)))
}

fn camera_name(exif: &Exif) -> String {
    let text = |tag| {
        exif.get_field(tag, In::PRIMARY)
            .map(|f| {
                f.display_value()
                    .to_string()
                    .trim_matches('"')
                    .trim()
                    .to_string()
            })
            .unwrap_or_default()
    };
    [text(Tag::Make), text(Tag::Model)]
        .into_iter()
        .filter(|s| !s.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

fn ascii(exif: &Exif, tag: Tag) -> Option<&[u8]> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Ascii(v) => v.first().map(Vec::as_slice),
        _ => None,
    }
}

fn rationals(exif: &Exif, tag: Tag) -> Option<Vec<f64>> {
    match &exif.get_field(tag, In::PRIMARY)?.value {
        Value::Rational(v) => Some(v.iter().map(|r| r.to_f64()).collect()),
        _ => None,
    }
}

fn rational(exif: &Exif, tag: Tag) -> Option<f64> {
    rationals(exif, tag)?
        .first()
        .copied()
        .filter(|v| v.is_finite())
}

/// `DateTimeOriginal` with its sub-seconds and UTC offset, in ns.
fn capture_time(exif: &Exif) -> Option<(i64, bool)> {
    let mut t = exif::DateTime::from_ascii(ascii(exif, Tag::DateTimeOriginal)?).ok()?;
    if let Some(sub) = ascii(exif, Tag::SubSecTimeOriginal) {
        let _ = t.parse_subsec(sub);
    }
    if let Some(offset) = ascii(exif, Tag::OffsetTimeOriginal) {
        let _ = t.parse_offset(offset);
    }
    let civil = jiff::civil::DateTime::new(
        i16::try_from(t.year).ok()?,
        i8::try_from(t.month).ok()?,
        i8::try_from(t.day).ok()?,
        i8::try_from(t.hour).ok()?,
        i8::try_from(t.minute).ok()?,
        i8::try_from(t.second).ok()?,
        i32::try_from(t.nanosecond.unwrap_or(0)).ok()?,
    )
    .ok()?;
    let offset = jiff::tz::Offset::from_seconds(i32::from(t.offset.unwrap_or(0)) * 60).ok()?;
    let instant = offset.to_timestamp(civil).ok()?;
    i64::try_from(instant.as_nanosecond())
        .ok()
        .map(|ns| (ns, t.offset.is_some()))
}

/// EXIF's GPS position; `altitude` (DJI's absolute altitude) over EXIF's;
/// an error where it is tagged but is not a place on the Earth.
fn position(exif: &Exif, altitude: Option<f64>) -> Result<Option<Geodetic>, String> {
    tagged_position(exif, altitude)
        .map(|g| {
            g.check()
                .map(|()| g)
                .map_err(|e| format!("its GPS position is not a place on the Earth: {e}"))
        })
        .transpose()
}

fn tagged_position(exif: &Exif, altitude: Option<f64>) -> Option<Geodetic> {
    let degrees = |tag, reference, negative: u8| {
        let dms = rationals(exif, tag)?;
        let value = dms
            .iter()
            .zip([1.0, 60.0, 3600.0])
            .map(|(v, d)| v / d)
            .sum::<f64>();
        let sign = match ascii(exif, reference).and_then(|r| r.first()) {
            Some(r) if r.eq_ignore_ascii_case(&negative) => -1.0,
            _ => 1.0,
        };
        Some(sign * value)
    };
    let latitude_deg = degrees(Tag::GPSLatitude, Tag::GPSLatitudeRef, b'S')?;
    let longitude_deg = degrees(Tag::GPSLongitude, Tag::GPSLongitudeRef, b'W')?;
    let exif_altitude = rational(exif, Tag::GPSAltitude).map(|a| {
        let below = exif
            .get_field(Tag::GPSAltitudeRef, In::PRIMARY)
            .and_then(|f| f.value.get_uint(0))
            == Some(1);
        if below { -a } else { a }
    });
    Some(Geodetic {
        latitude_deg,
        longitude_deg,
        altitude_m: altitude.or(exif_altitude)?,
    })
}

/// The best lens model the tags give; an error where that is not a lens's.
fn lens(
    dji: &BTreeMap<String, String>,
    exif: Option<&Exif>,
    width: u32,
    height: u32,
) -> Result<Option<(Intrinsics, LensSource)>, String> {
    let Some((lens, source)) = tagged_lens(dji, exif, width, height)? else {
        return Ok(None);
    };
    match lens.check() {
        Ok(()) => Ok(Some((lens, source))),
        Err(e) => Err(format!("{} is not a lens's: {e}", source.describe())),
    }
}

fn tagged_lens(
    dji: &BTreeMap<String, String>,
    exif: Option<&Exif>,
    width: u32,
    height: u32,
) -> Result<Option<(Intrinsics, LensSource)>, String> {
    let (w, h) = (f64::from(width), f64::from(height));
    let number = |name: &str| dji.get(name).and_then(|v| v.parse::<f64>().ok());
    let pinhole = |f: f64, cx: f64, cy: f64| Intrinsics {
        width,
        height,
        fx: f,
        fy: f,
        cx,
        cy,
        distortion: Distortion::None,
    };
    // "date;fx,fy,cx,cy,k1,k2,p1,p2,k3", the principal point from the centre.
    let dewarp = dji.get("DewarpData").and_then(|text| {
        let values: Vec<f64> = text
            .rsplit(';')
            .next()?
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()?;
        let [fx, fy, cx, cy, k1, k2, p1, p2, k3] = values[..] else {
            return None;
        };
        // Photos DJI already undistorted keep only the pinhole.
        let dewarped = number("DewarpFlag") == Some(1.0);
        let distortion = match dewarped {
            true => Ok(Distortion::None),
            false => Distortion::from_ros("plumb_bob", &[k1, k2, p1, p2, k3]),
        };
        // Uncalibrated cameras write zeros: the next tag's lens then.
        (fx > 0.0 && fy > 0.0).then(|| {
            distortion.map(|distortion| Intrinsics {
                width,
                height,
                fx,
                fy,
                cx: w / 2.0 + cx,
                cy: h / 2.0 + cy,
                distortion,
            })
        })
    });
    let dewarp = dewarp
        .transpose()
        .map_err(|e| format!("{}: {e}", LensSource::DewarpData.describe()))?;
    let calibrated = number("CalibratedFocalLength")
        .filter(|f| *f > 0.0)
        .map(|f| {
            let cx = number("CalibratedOpticalCenterX").unwrap_or(w / 2.0);
            let cy = number("CalibratedOpticalCenterY").unwrap_or(h / 2.0);
            pinhole(f, cx, cy)
        });
    let focal_plane = exif.and_then(|e| {
        let f_mm = rational(e, Tag::FocalLength)?;
        let per_unit = rational(e, Tag::FocalPlaneXResolution)?;
        let unit_mm = match e
            .get_field(Tag::FocalPlaneResolutionUnit, In::PRIMARY)
            .and_then(|f| f.value.get_uint(0))
            .unwrap_or(2)
        {
            3 => 10.0,
            4 => 1.0,
            5 => 0.001,
            _ => 25.4,
        };
        Some(pinhole(f_mm * per_unit / unit_mm, w / 2.0, h / 2.0)).filter(|k| k.fx > 0.0)
    });
    let film = exif.and_then(|e| {
        let f35 = f64::from(
            e.get_field(Tag::FocalLengthIn35mmFilm, In::PRIMARY)?
                .value
                .get_uint(0)?,
        );
        Some(pinhole(
            f35 * w.hypot(h) / FILM_DIAGONAL_MM,
            w / 2.0,
            h / 2.0,
        ))
        .filter(|k| k.fx > 0.0)
    });
    Ok([
        (dewarp, LensSource::DewarpData),
        (calibrated, LensSource::CalibratedFocalLength),
        (focal_plane, LensSource::FocalPlane),
        (film, LensSource::FilmEquivalent),
    ]
    .into_iter()
    .find_map(|(k, source)| Some((k?, source))))
}
