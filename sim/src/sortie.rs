//! A flight recorded as sorties: cut at battery changes, one recording
//! each, as a structure too big for one battery is flown. Every sortie
//! records the same flight model's messages; a frame, a pose or a `/tf`
//! goes to the sortie whose stretch of time holds its stamp. The SLAM
//! frame is the first sortie's throughout (the map then comes with the
//! last), or, with an offset, the later sorties record in another frame
//! (as a SLAM system started afresh after a landing does), each with its
//! own map.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use serde::Serialize;

use crate::SimError;
use crate::record::Recorder;
use crate::repeat::FrameOffset;
use postflight_core::serde_pose::PoseJson;

/// How a flight is cut into sorties.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SortieOptions {
    /// Recordings, one per battery; 1 records the flight whole.
    pub count: u32,
    /// The later sorties' SLAM frame against the first's; `None`: the
    /// first's.
    pub offset: Option<FrameOffset>,
}

impl Default for SortieOptions {
    fn default() -> Self {
        Self {
            count: 1,
            offset: None,
        }
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

/// A sortie's stretch of the flight, as its recording needs it.
#[derive(Debug, Clone, Copy)]
pub struct SortieSpan {
    /// Its start and end, seconds into the flight.
    pub start_s: f64,
    pub end_s: f64,
    /// Its SLAM frame: a world point `p` is recorded at `slam * p`.
    pub slam: Isometry3<f64>,
    /// Whether its recording holds the map.
    pub with_map: bool,
}

/// The recordings a flight is written into.
pub struct Sorties {
    stretches: Vec<Stretch>,
    recorders: Vec<Recorder>,
    names: Vec<String>,
    /// Each sortie's SLAM frame: a world point `p` is recorded at `slam * p`.
    slam: Vec<Isometry3<f64>>,
}

impl Sorties {
    /// The recordings in `out` for a flight of `frame_times` (seconds,
    /// `duration_s` long): `flight.mcap` when whole, else `sortie-1.mcap`
    /// and on; with `moving_tf`, each with a `/tf` channel.
    pub fn create(
        out: &Path,
        options: &SortieOptions,
        frame_times: &[f64],
        duration_s: f64,
        moving_tf: bool,
    ) -> Result<Self, SimError> {
        // `count` is 1 to the frames (checked before anything is written).
        let names: Vec<String> = match options.count {
            1 => vec!["flight.mcap".to_string()],
            k => (1..=k).map(|s| format!("sortie-{s}.mcap")).collect(),
        };
        let later = options
            .offset
            .map_or_else(Isometry3::identity, |o| o.isometry());
        Ok(Self {
            stretches: stretches(frame_times, duration_s, options.count),
            recorders: names
                .iter()
                .map(|name| Recorder::create(&out.join(name), moving_tf))
                .collect::<Result<_, _>>()?,
            slam: (0..options.count)
                .map(|s| if s == 0 { Isometry3::identity() } else { later })
                .collect(),
            names,
        })
    }

    /// The sortie whose stretch holds `t` seconds.
    fn index_at(&self, t: f64) -> usize {
        self.stretches
            .iter()
            .rposition(|s| s.start_s <= t)
            .unwrap_or(0)
    }

    /// The recording of the sortie flying at `t` seconds, and its SLAM frame.
    pub fn at(&mut self, t: f64) -> (&mut Recorder, Isometry3<f64>) {
        let s = self.index_at(t);
        (&mut self.recorders[s], self.slam[s])
    }

    /// Each sortie's recording with what it holds once, to write that.
    pub fn each(&mut self) -> impl Iterator<Item = (&mut Recorder, SortieSpan)> {
        let spans: Vec<SortieSpan> = (0..self.recorders.len())
            .map(|i| SortieSpan {
                start_s: self.stretches[i].start_s,
                end_s: self.stretches[i].end_s,
                slam: self.slam[i],
                with_map: self.records_map(i),
            })
            .collect();
        self.recorders.iter_mut().zip(spans)
    }

    /// Whether a sortie records the map: the last, or, where the later
    /// sorties have a frame of their own, each.
    fn records_map(&self, sortie: usize) -> bool {
        sortie + 1 == self.recorders.len() || self.slam.iter().any(|s| *s != self.slam[0])
    }

    /// Close every recording; their paths.
    pub fn finish(self, out: &Path) -> Result<Vec<PathBuf>, SimError> {
        for r in self.recorders {
            r.finish()?;
        }
        Ok(self.names.iter().map(|n| out.join(n)).collect())
    }

    /// What truth.json says of the sorties; `None` for a whole flight.
    pub fn truth(&self, stamp: impl Fn(f64) -> i64) -> Option<Vec<SortieTruth>> {
        (self.recorders.len() > 1).then(|| {
            self.stretches
                .iter()
                .enumerate()
                .map(|(i, s)| SortieTruth {
                    recording: self.names[i].clone(),
                    first_frame: s.frames.0,
                    frames: s.frames.1 - s.frames.0,
                    start_ns: stamp(s.start_s),
                    end_ns: stamp(s.end_s),
                    slam_from_world: PoseJson::from(&self.slam[i]),
                    map: self.records_map(i),
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
