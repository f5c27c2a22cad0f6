//! The run log (`pipeline.json`): which stages `postflight run` completed in
//! a run directory, on which inputs and settings (a fingerprint), and how
//! long each took. A stage whose fingerprint still matches is not run again,
//! so an interrupted run resumes where it stopped.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::Error;
use crate::run_dir::RunDir;

/// The run log's file in the run directory.
pub const RUN_LOG: &str = "pipeline.json";

#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct RunLog {
    pub postflight_version: String,
    /// The stage started last and not finished: running now, or cut off.
    pub running: Option<String>,
    /// Completed stages, in pipeline order.
    pub stages: Vec<StageRecord>,
    /// The shares of the flight's detect done so far by `postflight batch`
    /// tasks (`detect 2/4`), each with the detect fingerprint it ran under;
    /// the last one done merges them into the detect stage.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub detect_shares: BTreeMap<String, String>,
}

/// One completed stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct StageRecord {
    pub stage: String,
    /// SHA-256 over the stage's settings, the contents of its input files
    /// and the previous stage's fingerprint.
    pub fingerprint: String,
    /// Input files from outside the run directory, by role (`flight`, `model`, ...).
    pub inputs: BTreeMap<String, InputFile>,
    pub seconds: f64,
    /// When it finished (RFC 3339, UTC).
    pub finished: String,
}

/// An input file as a stage read it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct InputFile {
    pub path: PathBuf,
    pub sha256: String,
    #[serde(default)]
    pub size_bytes: u64,
    /// Modification time, nanoseconds since 1970.
    #[serde(default)]
    pub modified_ns: i64,
}

impl InputFile {
    /// The file at `path` as it is now. Its SHA-256 is taken from a `known`
    /// file with the same path, size and modification time, so a resumed
    /// run does not read a flight of many gigabytes again; else it is read.
    /// A directory (a folder of photos) is its files together: their
    /// sizes added, the latest modification, and the SHA-256 of their
    /// names and SHA-256s.
    pub fn describe(path: &Path, known: &[InputFile]) -> Result<Self, Error> {
        let path = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
        let files = files_of(&path)?;
        let mut size_bytes = 0;
        let mut modified_ns = 0;
        for (_, meta) in &files {
            size_bytes += meta.len();
            let modified = meta
                .modified()
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_nanos() as i64);
            modified_ns = modified_ns.max(modified);
        }
        let same = known.iter().find(|k| {
            k.path == path
                && k.size_bytes == size_bytes
                && k.modified_ns == modified_ns
                && modified_ns != 0
        });
        let sha256 = match (same, path.is_dir()) {
            (Some(k), _) => k.sha256.clone(),
            (None, false) => sha256_file(&path)?,
            (None, true) => {
                let mut listing = String::new();
                for (file, _) in &files {
                    let name = file.file_name().unwrap_or_default().to_string_lossy();
                    listing.push_str(&format!("{}  {name}\n", sha256_file(file)?));
                }
                sha256(listing.as_bytes())
            }
        };
        Ok(Self {
            path,
            sha256,
            size_bytes,
            modified_ns,
        })
    }
}

/// The file at `path`, or a directory's files in name order, with their
/// metadata.
fn files_of(path: &Path) -> Result<Vec<(PathBuf, std::fs::Metadata)>, Error> {
    let open = |cause| Error::Open {
        path: path.to_owned(),
        cause,
    };
    let meta = std::fs::metadata(path).map_err(open)?;
    if !meta.is_dir() {
        return Ok(vec![(path.to_owned(), meta)]);
    }
    let mut files = Vec::new();
    for entry in std::fs::read_dir(path).map_err(open)? {
        let entry = entry.map_err(open)?;
        let meta = entry.metadata().map_err(open)?;
        if meta.is_file() {
            files.push((entry.path(), meta));
        }
    }
    files.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(files)
}

impl RunLog {
    /// The log of `dir`, or an empty one when no run has been logged there.
    pub fn read(dir: &RunDir) -> Result<Self, Error> {
        if dir.file(RUN_LOG).is_file() {
            dir.read_json(RUN_LOG)
        } else {
            Ok(Self::default())
        }
    }

    pub fn write(&self, dir: &RunDir) -> Result<(), Error> {
        dir.write_json(RUN_LOG, self)
    }

    pub fn record(&self, stage: &str) -> Option<&StageRecord> {
        self.stages.iter().find(|r| r.stage == stage)
    }

    /// Forget `stage` (before running it again); forgetting detect forgets
    /// its shares.
    pub fn forget(&mut self, stage: &str) {
        self.stages.retain(|r| r.stage != stage);
        if stage == crate::Stage::Detect.name() {
            self.detect_shares.clear();
        }
    }

    /// Seconds per completed stage.
    pub fn timings(&self) -> BTreeMap<String, f64> {
        self.stages
            .iter()
            .map(|r| (r.stage.clone(), r.seconds))
            .collect()
    }
}

/// SHA-256 of a file's contents, in hex (as `sha256sum` prints it).
pub fn sha256_file(path: &Path) -> Result<String, Error> {
    let open = |cause| Error::Open {
        path: path.to_owned(),
        cause,
    };
    let mut file = std::fs::File::open(path).map_err(open)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = file.read(&mut buf).map_err(open)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hex::encode(hasher.finalize()))
}

/// SHA-256 of bytes, in hex.
pub fn sha256(bytes: &[u8]) -> String {
    hex::encode(Sha256::digest(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hashes_like_sha256sum() {
        // `printf abc | sha256sum`
        assert_eq!(
            sha256(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, b"abc").unwrap();
        assert_eq!(sha256_file(&path).unwrap(), sha256(b"abc"));
    }

    #[test]
    fn an_unchanged_file_keeps_its_hash_and_a_changed_one_is_read_again() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, b"abc").unwrap();
        let first = InputFile::describe(&path, &[]).unwrap();
        assert_eq!(first.sha256, sha256(b"abc"));
        // A stale hash for the same path, size and time is trusted, not re-read.
        let known = InputFile {
            sha256: "known".into(),
            ..first.clone()
        };
        assert_eq!(
            InputFile::describe(&path, std::slice::from_ref(&known))
                .unwrap()
                .sha256,
            "known"
        );
        std::fs::write(&path, b"abcd").unwrap();
        assert_eq!(
            InputFile::describe(&path, &[known]).unwrap().sha256,
            sha256(b"abcd")
        );
    }

    #[test]
    fn a_missing_log_is_empty_and_a_written_one_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        assert_eq!(RunLog::read(&run).unwrap(), RunLog::default());
        let mut log = RunLog {
            postflight_version: "0".into(),
            running: Some("detect".into()),
            stages: vec![StageRecord {
                stage: "ingest".into(),
                fingerprint: "f".into(),
                inputs: BTreeMap::new(),
                seconds: 1.5,
                finished: crate::time::now_rfc3339(),
            }],
            detect_shares: BTreeMap::from([("2/4".into(), "f2".into())]),
        };
        log.write(&run).unwrap();
        assert_eq!(RunLog::read(&run).unwrap(), log);
        assert_eq!(log.timings()["ingest"], 1.5);
        log.forget("ingest");
        assert!(log.record("ingest").is_none());
        assert_eq!(log.detect_shares.len(), 1, "ingest's record goes alone");
        // Forgetting detect forgets the shares it was made of.
        log.forget("detect");
        assert!(log.detect_shares.is_empty());
    }
}
