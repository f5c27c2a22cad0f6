//! A flown plan as given to `--plan`: `plan.json`, or a waypoint path CSV
//! (`X,Y,Z,Yaw`, GATSBI's and `replan.csv`'s) read with either yaw unit.
#![no_main]
use postflight_core::plan::{PlanFile, YawUnit};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    // The first byte picks the file's kind and the yaw unit.
    let Some((&pick, text)) = data.split_first() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let name = if pick & 1 == 0 {
        "plan.json"
    } else {
        "path.csv"
    };
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    let yaw = if pick & 2 == 0 {
        YawUnit::Radians
    } else {
        YawUnit::Degrees
    };
    let _ = PlanFile { path, yaw }.load();
});
