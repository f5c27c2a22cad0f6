//! Repeat inspections with known change: the structure and the cracks of an
//! earlier simulated flight, some grown by known amounts and new ones added,
//! flown again and recorded in another SLAM frame (a second flight's SLAM
//! starts somewhere else). `truth.json` lists every change and the frame.

use std::path::PathBuf;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use postflight_core::serde_pose::PoseJson;
use serde::{Deserialize, Serialize};

use crate::crack::{Cracks, WidthRange};
use crate::error::SimError;
use crate::rng::Rng;
use crate::scene::Scene;

/// A repeat of an earlier simulated flight: given by `--repeat-of`, which
/// the other flags here need.
#[derive(Debug, Clone, clap::Args)]
pub struct Repeat {
    /// Fly an earlier simulated flight's structure and cracks again (its
    /// directory), changed by --grow and --new and recorded in another SLAM
    /// frame (--frame-offset); truth.json lists every change.
    // Not required on its own: the repeat is there when one of its flags is.
    #[arg(
        id = "repeat_of",
        long = "repeat-of",
        value_name = "FLIGHT_DIR",
        required = false
    )]
    pub of: PathBuf,
    /// With --repeat-of: the share of cracks that grow (each by a quarter
    /// to three quarters of its length).
    #[arg(
        long,
        default_value_t = 0.2,
        value_name = "SHARE",
        requires = "repeat_of"
    )]
    pub grow: f64,
    /// With --repeat-of: the share of cracks that open wider (each 1.4 to
    /// 2.2 times; the earlier flight needs --crack-widths).
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "SHARE",
        requires = "repeat_of"
    )]
    pub widen: f64,
    /// With --repeat-of: new cracks.
    #[arg(long, default_value_t = 5, value_name = "N", requires = "repeat_of")]
    pub new: usize,
    /// With --repeat-of: this flight's SLAM frame against the earlier one's:
    /// a shift (metres) and a yaw (degrees).
    #[arg(
        long,
        default_value = "0,0,0,0",
        value_name = "X,Y,Z,YAW_DEG",
        value_parser = FrameOffset::parse,
        allow_hyphen_values = true,
        requires = "repeat_of"
    )]
    pub frame_offset: FrameOffset,
}

/// A gravity-aligned frame change (as between two LIO-SAM sessions):
/// `x,y,z` metres and a yaw about z in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameOffset {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub yaw_deg: f64,
}

impl FrameOffset {
    /// `X,Y,Z,YAW_DEG`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match postflight_core::setting::comma_numbers(s).as_deref() {
            Some(&[x, y, z, yaw_deg]) => Ok(Self { x, y, z, yaw_deg }),
            _ => Err(format!(
                "expected four numbers X,Y,Z,YAW_DEG (metres, degrees), not '{s}'"
            )),
        }
    }

    /// The earlier flight's frame to this one's: a point `p` recorded there
    /// is recorded at `isometry() * p` here.
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.x, self.y, self.z),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw_deg.to_radians()),
        )
    }
}

/// What the earlier flight's `truth.json` says about the world.
#[derive(Debug, Deserialize)]
pub(crate) struct Earlier {
    pub scene: String,
    pub seed: u64,
    #[serde(default)]
    crack_widths: Option<WidthRange>,
    cracks: Vec<serde::de::IgnoredAny>,
    #[serde(default)]
    repeat: Option<serde::de::IgnoredAny>,
}

impl Earlier {
    /// The earlier flight of `repeat`, checked to be an original flight of
    /// the scene `scene`.
    pub fn read(repeat: &Repeat, scene: &str) -> Result<Self, SimError> {
        let path = repeat.of.join("truth.json");
        let bad = |why: String| SimError::Repeat {
            path: path.clone(),
            why,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| {
            bad(format!(
                "cannot read it ({e}); give the directory of a simulated flight"
            ))
        })?;
        let earlier: Self = serde_json::from_str(&text)
            .map_err(|e| bad(format!("not a simulator's truth.json ({e})")))?;
        if earlier.repeat.is_some() {
            return Err(bad("is itself a repeat; repeat the original flight".into()));
        }
        if earlier.scene != scene {
            return Err(bad(format!(
                "flew the structure '{}', not '{scene}'; give the same --scene or --mesh",
                earlier.scene
            )));
        }
        for (flag, share) in [("--grow", repeat.grow), ("--widen", repeat.widen)] {
            if !(0.0..=1.0).contains(&share) {
                return Err(bad(format!("{flag} {share} is not a share from 0 to 1")));
            }
        }
        if repeat.widen > 0.0 && earlier.crack_widths.is_none() {
            return Err(bad(
                "has cracks of one even width; --widen needs a flight simulated with --crack-widths"
                    .into(),
            ));
        }
        Ok(earlier)
    }

    /// Its cracks, drawn again as it drew them.
    pub fn cracks(&self, scene: &Scene) -> Cracks {
        let mut cracks = Cracks::generate(
            scene,
            self.cracks.len(),
            &mut Rng::stream(self.seed, "cracks"),
        );
        if let Some(range) = self.crack_widths {
            cracks.taper(range, &mut Rng::stream(self.seed, "crack widths"));
        }
        cracks
    }

    /// The widths its cracks taper between, if they do.
    pub fn crack_widths(&self) -> Option<WidthRange> {
        self.crack_widths
    }
}

/// How one crack changed since the earlier flight.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CrackChange {
    pub id: u32,
    pub change: Change,
    /// Its length in the earlier flight, metres (none for a new crack).
    pub length_before_m: Option<f64>,
    pub length_m: f64,
    /// Its widest in the earlier flight and now, millimetres (cracks that
    /// taper; none before for a new crack).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width_before_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width_mm: Option<f64>,
    /// It opened wider since the earlier flight.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub widened: bool,
}

#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Change {
    Unchanged,
    Grown,
    New,
}

/// `truth.json`'s account of a repeat flight.
#[derive(Debug, Clone, Serialize)]
pub struct RepeatTruth {
    pub of: PathBuf,
    pub frame_offset: FrameOffset,
    /// The earlier flight's frame in this one's (`T_this_earlier`).
    pub earlier_to_this: PoseJson,
    /// Every crack of this flight, and the earlier flight's cracks' fate.
    pub changes: Vec<CrackChange>,
}

/// The earlier flight's cracks changed as `repeat` asks (grown at their
/// tips by a quarter to three quarters of their length, new ones added),
/// and the change of each; in the earlier flight's frame.
pub(crate) fn change(
    scene: &Scene,
    mut cracks: Cracks,
    widths: Option<WidthRange>,
    repeat: &Repeat,
    seed: u64,
) -> (Cracks, Vec<CrackChange>) {
    let mut rng = Rng::stream(seed, "crack growth");
    let mut widening = Rng::stream(seed, "crack widening");
    let tapered = widths.is_some();
    let mut changes: Vec<CrackChange> = Vec::new();
    for crack in &mut cracks.0 {
        let before = crack.length();
        let width_before = crack.width;
        let widened = tapered && widening.uniform() < repeat.widen;
        if widened {
            crack.widen(widening.range(1.4, 2.2));
        }
        let grows = rng.uniform() < repeat.grow;
        let by = before * rng.range(0.25, 0.75);
        let grown = if grows {
            crack.extend(scene, by, &mut rng)
        } else {
            0.0
        };
        changes.push(CrackChange {
            id: crack.id,
            // Growth a face edge stopped short is no growth to see.
            change: if grown > 0.1 * before {
                Change::Grown
            } else {
                Change::Unchanged
            },
            length_before_m: Some(before),
            length_m: crack.length(),
            width_before_mm: tapered.then_some(width_before * 1000.0),
            width_mm: tapered.then_some(crack.width * 1000.0),
            widened,
        });
    }
    let old = cracks.0.len();
    cracks.add(scene, repeat.new, &mut Rng::stream(seed, "new cracks"));
    if let Some(range) = widths {
        let mut rng = Rng::stream(seed, "new crack widths");
        cracks.0[old..]
            .iter_mut()
            .for_each(|c| c.taper(range, &mut rng));
    }
    for crack in &cracks.0[old..] {
        changes.push(CrackChange {
            id: crack.id,
            change: Change::New,
            length_before_m: None,
            length_m: crack.length(),
            width_before_mm: None,
            width_mm: tapered.then_some(crack.width * 1000.0),
            widened: false,
        });
    }
    (cracks, changes)
}

/// The truth of a repeat: where it came from and what changed.
pub(crate) fn truth(repeat: &Repeat, changes: Vec<CrackChange>) -> RepeatTruth {
    RepeatTruth {
        of: std::path::absolute(&repeat.of).unwrap_or_else(|_| repeat.of.clone()),
        frame_offset: repeat.frame_offset,
        earlier_to_this: PoseJson::from(&repeat.frame_offset.isometry()),
        changes,
    }
}
