//! A flight recorded as sorties: cut at battery changes, one recording
//! each, as a structure too big for one battery is flown. Every sortie
//! records the same flight model's messages; a frame, a pose or a `/tf`
//! goes to the sortie whose stretch of time holds its stamp. The SLAM
//! frame is the first sortie's throughout (the map then comes with the
//! last), or, with an offset, the later sorties record in another frame
//! (as a SLAM system started afresh after a landing does), each with its
//! own map. A team's drones fly the stretches at once, each recording
//! from the same start.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde::Serialize;

use crate::SimError;
use crate::record::Recorder;
use crate::repeat::FrameOffset;
use postflight_core::serde_pose::PoseJson;

/// How a flight is cut into sorties, or shared by a team.
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct SortieOptions {
    /// Record the flight as this many sorties, cut at battery changes
    /// (frames shared out evenly): sortie-1.mcap and on, the map in the
    /// last; truth.json says which frames each holds.
    #[arg(long = "sorties", default_value_t = 1, value_name = "K")]
    pub count: u32,
    /// Fly the flight as a team of this many drones at once, a stretch of
    /// the plan each (drone-1.mcap and on, each recording's clock from the
    /// same start): with --sortie-offset each drone in a SLAM frame of its
    /// own (the offset once more for each), and with --camera-only the
    /// first drone alone mapping.
    #[arg(long, value_name = "N", conflicts_with = "count")]
    pub drones: Option<u32>,
    /// With --sorties: the later sorties record in another SLAM frame,
    /// this far from the first's (a shift in metres and a yaw in degrees),
    /// each with its own map.
    #[arg(long = "sortie-offset", value_name = "X,Y,Z,YAW_DEG", value_parser = FrameOffset::parse, allow_hyphen_values = true)]
    pub offset: Option<FrameOffset>,
    /// With --sortie-offset: the later sorties (or drones) record no map,
    /// as a drone with a camera and odometry only (the map is the first
    /// sortie's).
    #[arg(long, requires = "offset")]
    pub camera_only: bool,
}

impl SortieOptions {
    /// Recordings: one per sortie, or per drone of a team.
    pub fn recordings(&self) -> u32 {
        self.drones.unwrap_or(self.count)
    }

    /// The stretches are flown at once by a team, a drone each, each
    /// recording's clock from the same start; with an offset each drone
    /// after the first has a SLAM frame of its own.
    pub fn team(&self) -> bool {
        self.drones.is_some()
    }
}

/// Where each sortie starts and ends, and the frames it holds.
#[derive(Debug, Clone, PartialEq)]
struct Stretch {
    /// Its first frame's index and the index past its last.
    frames: (u32, u32),
    /// Its start and end, seconds into the flight.
    start_s: f64,
    end_s: f64,
}

/// The stretches of a flight of `frame_times` cut into `count` sorties of
/// (nearly) as many frames, each cut half-way between two frames.
fn stretches(frame_times: &[f64], duration_s: f64, count: u32) -> Vec<Stretch> {
    let n = frame_times.len() as u32;
    let first = |s: u32| (u64::from(s) * u64::from(n)).div_ceil(u64::from(count)) as u32;
    let cut = |s: u32| match s {
        0 => 0.0,
        s if s == count => duration_s,
        s => {
            let i = first(s) as usize;
            (frame_times[i - 1] + frame_times[i]) / 2.0
        }
    };
    (0..count)
        .map(|s| Stretch {
            frames: (first(s), first(s + 1)),
            start_s: cut(s),
            end_s: cut(s + 1),
        })
        .collect()
}

/// One sortie: its recording's file name, its stretch, its SLAM frame and
/// whether its recording holds the map.
#[derive(Debug, Clone)]
pub struct Sortie {
    pub name: String,
    stretch: Stretch,
    /// Its SLAM frame: a world point `p` is recorded at `slam * p`.
    pub slam: Isometry3<f64>,
    pub with_map: bool,
    /// What its recording's clock is behind the flight's: a team's drones
    /// all start at the flight's start.
    shift_s: f64,
}

impl Sortie {
    /// The stamp its recording gives the flight's time `t` (seconds).
    pub fn stamp(&self, t: f64) -> i64 {
        crate::ns(t - self.shift_s)
    }

    /// Its start and end, seconds into the flight.
    pub fn start_s(&self) -> f64 {
        self.stretch.start_s
    }

    pub fn end_s(&self) -> f64 {
        self.stretch.end_s
    }
}

/// The recordings a flight is written into, one per sortie.
pub struct Sorties {
    sorties: Vec<Sortie>,
    recorders: Vec<Recorder>,
}

impl Sorties {
    /// The recordings in `out` for a flight of `frame_times` (seconds,
    /// `duration_s` long): `flight.mcap` when whole, else `sortie-1.mcap`
    /// and on; with `moving_tf`, each with a `/tf` channel, and with
    /// `gps`, a GPS channel. The map goes with the last, or, where the later
    /// sorties have a frame of their own, with each (but for camera-only
    /// ones: then with the first).
    pub fn create(
        out: &Path,
        options: &SortieOptions,
        frame_times: &[f64],
        duration_s: f64,
        (moving_tf, gps): (bool, bool),
    ) -> Result<Self, SimError> {
        // `count` is 1 to the frames (checked before anything is written).
        let count = options.recordings() as usize;
        let later = options.offset.map(|o| o.isometry());
        // A team's drone k is offset k times; sorties after the first, once.
        let slam = |i: usize| match (later, options.team()) {
            (Some(o), true) => (0..i).fold(Isometry3::identity(), |t, _| o * t),
            (Some(o), false) if i > 0 => o,
            _ => Isometry3::identity(),
        };
        let sorties: Vec<Sortie> = stretches(frame_times, duration_s, options.recordings())
            .into_iter()
            .enumerate()
            .map(|(i, stretch)| Sortie {
                name: match (count, options.team()) {
                    (1, _) => "flight.mcap".to_string(),
                    (_, true) => format!("drone-{}.mcap", i + 1),
                    (_, false) => format!("sortie-{}.mcap", i + 1),
                },
                shift_s: if options.team() { stretch.start_s } else { 0.0 },
                stretch,
                slam: slam(i),
                with_map: match (later.is_some(), options.camera_only) {
                    (true, true) => i == 0,
                    (true, false) => true,
                    (false, _) => i + 1 == count,
                },
            })
            .collect();
        let recorders = sorties
            .iter()
            .map(|s| Recorder::create(&out.join(&s.name), moving_tf, gps))
            .collect::<Result<_, _>>()?;
        Ok(Self { sorties, recorders })
    }

    /// The recording of the sortie flying at `t` seconds, its SLAM frame,
    /// and the stamp its clock gives `t`.
    pub fn at(&mut self, t: f64) -> (&mut Recorder, Isometry3<f64>, i64) {
        let s = self.index_at(t);
        let stamp = self.sorties[s].stamp(t);
        (&mut self.recorders[s], self.sorties[s].slam, stamp)
    }

    /// The stamp the recording flying at `t` gives it.
    pub fn stamp(&self, t: f64) -> i64 {
        self.sorties[self.index_at(t)].stamp(t)
    }

    fn index_at(&self, t: f64) -> usize {
        self.sorties
            .iter()
            .rposition(|s| s.start_s() <= t)
            .unwrap_or(0)
    }

    /// Each sortie's recording, to write what each holds once.
    pub fn each(&mut self) -> impl Iterator<Item = (&mut Recorder, &Sortie)> {
        self.recorders.iter_mut().zip(&self.sorties)
    }

    /// Close every recording; their paths.
    pub fn finish(self, out: &Path) -> Result<Vec<PathBuf>, SimError> {
        for r in self.recorders {
            r.finish()?;
        }
        Ok(self.sorties.iter().map(|s| out.join(&s.name)).collect())
    }

    /// What truth.json says of the sorties; `None` for a whole flight.
    pub fn truth(&self, stamp: impl Fn(f64) -> i64) -> Option<Vec<SortieTruth>> {
        (self.sorties.len() > 1).then(|| {
            self.sorties
                .iter()
                .map(|s| SortieTruth {
                    recording: s.name.clone(),
                    first_frame: s.stretch.frames.0,
                    frames: s.stretch.frames.1 - s.stretch.frames.0,
                    start_ns: stamp(s.start_s()),
                    end_ns: stamp(s.end_s()),
                    clock_behind_ns: stamp(s.shift_s) - stamp(0.0),
                    slam_from_world: PoseJson::from(&s.slam),
                    map: s.with_map,
                })
                .collect()
        })
    }
}

/// One sortie, in truth.json.
#[derive(Debug, Clone, Serialize)]
pub struct SortieTruth {
    /// Its recording's file name.
    pub recording: String,
    /// Its first frame's index (truth.json's `frames`) and how many frames
    /// it shot (dropped ones included).
    pub first_frame: u32,
    pub frames: u32,
    pub start_ns: i64,
    pub end_ns: i64,
    /// How far its recording's clock is behind the flight's (a team's
    /// drones all start together): its stamps are the flight's times less
    /// this.
    pub clock_behind_ns: i64,
    /// Its SLAM frame: a world point `p` is recorded at `slam_from_world * p`.
    pub slam_from_world: PoseJson,
    /// Whether its recording holds the map.
    pub map: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flight_is_cut_into_sorties_of_as_many_frames_half_way_between_two() {
        let times: Vec<f64> = (0..10).map(|i| f64::from(i) * 2.0 + 1.0).collect();
        let cut = stretches(&times, 21.0, 3);
        let frames: Vec<(u32, u32)> = cut.iter().map(|s| s.frames).collect();
        assert_eq!(frames, [(0, 4), (4, 7), (7, 10)]);
        // Frame 3 at 7 s, frame 4 at 9 s: the cut at 8 s.
        assert_eq!((cut[0].start_s, cut[0].end_s), (0.0, 8.0));
        assert_eq!((cut[1].start_s, cut[1].end_s), (8.0, 14.0));
        assert_eq!((cut[2].start_s, cut[2].end_s), (14.0, 21.0));
        // Whole: one stretch over everything.
        assert_eq!(
            stretches(&times, 21.0, 1),
            [Stretch {
                frames: (0, 10),
                start_s: 0.0,
                end_s: 21.0
            }]
        );
    }
}
