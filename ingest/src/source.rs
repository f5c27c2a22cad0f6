//! A flight's sources, one per sortie or drone: a recording (MCAP or a ROS
//! 1 bag) or a folder of photos.

use std::path::{Path, PathBuf};

use crate::error::IngestError;
use crate::photos::PhotoFolder;
use crate::recording::Recording;

/// One source of a flight, opened.
pub enum Source {
    Recording(Recording),
    Photos(PhotoFolder),
}

impl Source {
    /// A directory is a photo folder; a file, a recording.
    pub fn open(path: &Path) -> Result<Self, IngestError> {
        match path.is_dir() {
            true => PhotoFolder::open(path).map(Self::Photos),
            false => Recording::open(path).map(Self::Recording),
        }
    }

    pub fn path(&self) -> &Path {
        match self {
            Self::Recording(r) => r.path(),
            Self::Photos(p) => p.path(),
        }
    }

    /// Its bytes: the recording's, or the photos' together.
    pub fn len(&self) -> u64 {
        match self {
            Self::Recording(r) => r.len(),
            Self::Photos(p) => p.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The sources a `--flight` names: the file; a directory's MCAP and bag
/// files in name order (sortie-1.mcap, sortie-2.mcap, ...); a directory of
/// photos; or a directory of photo folders (a card's DCIM, a folder per
/// flight), in name order.
pub fn sources_in(path: &Path) -> Result<Vec<PathBuf>, IngestError> {
    if !path.is_dir() {
        return Ok(vec![path.to_owned()]);
    }
    let listed = std::fs::read_dir(path).map_err(|e| IngestError::NotRecording {
        path: path.to_owned(),
        why: e.to_string(),
    })?;
    let entries: Vec<PathBuf> = listed.flatten().map(|e| e.path()).collect();
    let mut recordings: Vec<PathBuf> = entries
        .iter()
        .filter(|p| p.is_file() && Recording::is_recording_name(p))
        .cloned()
        .collect();
    recordings.sort();
    if !recordings.is_empty() {
        return Ok(recordings);
    }
    if PhotoFolder::holds_photos(path) {
        return Ok(vec![path.to_owned()]);
    }
    let mut folders: Vec<PathBuf> = entries
        .into_iter()
        .filter(|p| p.is_dir() && PhotoFolder::holds_photos(p))
        .collect();
    folders.sort();
    if folders.is_empty() {
        return Err(IngestError::NoRecordingsIn {
            path: path.to_owned(),
        });
    }
    Ok(folders)
}
