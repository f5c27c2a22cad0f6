//! Defect localisation: places each detection on the SLAM map by casting
//! camera rays through its box into the voxel map, and fuses observations of
//! the same crack across frames into defect candidates (position, extent,
//! supporting views, best view). It owns the observations and defects tables;
//! it reads the flight model from `ingest` and detections from `detect`.
