//! The run directory: where every stage writes its outputs and reads its
//! inputs, so each stage can be rerun or inspected alone.
//!
//! Files are written whole or not at all (to a temporary name, then renamed),
//! and each stage writes its JSON summary last: a stage's outputs are
//! complete exactly when its summary exists.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use polars::prelude::*;

use crate::error::IngestError;

/// Files of the ingest stage.
pub mod files {
    pub const FRAMES: &str = "frames.parquet";
    pub const TRAJECTORY: &str = "trajectory.parquet";
    pub const CAMERAS: &str = "cameras.json";
    pub const INGEST: &str = "ingest.json";
}

#[derive(Debug, Clone)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// Create the directory if needed.
    pub fn create(path: &Path) -> Result<Self, IngestError> {
        std::fs::create_dir_all(path).map_err(|source| IngestError::Write {
            path: path.to_owned(),
            source,
        })?;
        Ok(Self {
            path: path.to_owned(),
        })
    }

    /// Open a run directory that a stage has completed (its `summary` file exists).
    pub fn open(path: &Path, summary: &str, stage: &str) -> Result<Self, IngestError> {
        if !path.join(summary).is_file() {
            return Err(IngestError::RunDir {
                path: path.to_owned(),
                why: format!(
                    "has no completed {stage} stage ({summary} is missing); run `postflight {stage}` into it first"
                ),
            });
        }
        Ok(Self {
            path: path.to_owned(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn file(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }

    /// Remove a file if present (a stage clears its summary before writing,
    /// so an interrupted stage never looks complete).
    pub fn remove(&self, name: &str) -> Result<(), IngestError> {
        match std::fs::remove_file(self.file(name)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(IngestError::Write {
                path: self.file(name),
                source: e,
            }),
            _ => Ok(()),
        }
    }

    /// Write `name` atomically with `write`.
    pub fn write_with(
        &self,
        name: &str,
        write: impl FnOnce(&mut File) -> Result<(), IngestError>,
    ) -> Result<(), IngestError> {
        let target = self.file(name);
        let tmp = self.file(&format!(".{name}.tmp"));
        let io = |source| IngestError::Write {
            path: target.clone(),
            source,
        };
        let mut file = File::create(&tmp).map_err(io)?;
        write(&mut file)?;
        file.sync_all().map_err(io)?;
        std::fs::rename(&tmp, &target).map_err(io)
    }

    /// Write `name` atomically with the text `text`.
    pub fn write_text(&self, name: &str, text: &str) -> Result<(), IngestError> {
        let path = self.file(name);
        self.write_with(name, |f| {
            f.write_all(text.as_bytes())
                .map_err(|source| IngestError::Write { path, source })
        })
    }

    pub fn write_json(&self, name: &str, value: &impl serde::Serialize) -> Result<(), IngestError> {
        let text = serde_json::to_string_pretty(value).expect("JSON-serialisable");
        self.write_text(name, &(text + "\n"))
    }

    pub fn read_json<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<T, IngestError> {
        let path = self.file(name);
        let text = std::fs::read_to_string(&path).map_err(|source| IngestError::Open {
            path: path.clone(),
            source,
        })?;
        serde_json::from_str(&text).map_err(|e| IngestError::RunDir {
            path,
            why: format!("unreadable ({e}); rerun the stage that wrote it"),
        })
    }

    pub fn write_table(&self, name: &str, df: &mut DataFrame) -> Result<(), IngestError> {
        let path = self.file(name);
        self.write_with(name, |f| {
            ParquetWriter::new(f)
                .finish(df)
                .map(|_| ())
                .map_err(|source| IngestError::Table { path, source })
        })
    }

    pub fn read_table(&self, name: &str) -> Result<DataFrame, IngestError> {
        let path = self.file(name);
        let file = File::open(&path).map_err(|source| IngestError::Open {
            path: path.clone(),
            source,
        })?;
        ParquetReader::new(file)
            .finish()
            .map_err(|source| IngestError::Table { path, source })
    }
}
