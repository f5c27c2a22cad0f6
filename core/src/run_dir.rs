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

use crate::error::Error;
use crate::outputs::Stage;
use crate::table::Row;

/// The record a stage keeps in a folder it fills (see [`RunDir::refill`]):
/// the names of the files it wrote there, as JSON.
pub const FOLDER_RECORD: &str = ".postflight-files.json";

/// A run directory: the outputs of the stages run on one flight.
#[derive(Debug, Clone)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// Create the directory if needed.
    pub fn create(path: &Path) -> Result<Self, Error> {
        std::fs::create_dir_all(path).map_err(|cause| Error::Write {
            path: path.to_owned(),
            cause,
        })?;
        Ok(Self {
            path: path.to_owned(),
        })
    }

    /// Open a run directory in which `stage` has completed.
    pub fn open(path: &Path, stage: Stage) -> Result<Self, Error> {
        let run = Self {
            path: path.to_owned(),
        };
        run.require(stage)?;
        Ok(run)
    }

    /// An error unless `stage` has completed here (its summary exists).
    pub fn require(&self, stage: Stage) -> Result<(), Error> {
        let summary = stage.summary_file();
        if self.file(summary).is_file() {
            return Ok(());
        }
        if !self.path.is_dir() {
            return Err(Error::RunDir {
                path: self.path.clone(),
                why: format!(
                    "no such directory; check the path given to {}",
                    crate::setting::inputs::RUN
                ),
            });
        }
        Err(Error::RunDir {
            path: self.path.clone(),
            why: format!(
                "has no completed {stage} stage ({summary} is missing); run `postflight {stage}` into it first"
            ),
        })
    }

    /// A stage's summary, `None` when the stage has not completed here.
    pub fn summary<T: serde::de::DeserializeOwned>(
        &self,
        stage: Stage,
    ) -> Result<Option<T>, Error> {
        let name = stage.summary_file();
        if self.file(name).is_file() {
            self.read_json(name).map(Some)
        } else {
            Ok(None)
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn file(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }

    /// Remove a file if present (a stage clears its summary before writing,
    /// so an interrupted stage never looks complete). Whatever is there and
    /// is not a file (a user's folder) is in the way: refused, never
    /// deleted.
    pub fn remove(&self, name: &str) -> Result<(), Error> {
        let path = self.file(name);
        if in_the_way(&path) {
            return Err(Error::InTheWay { path });
        }
        match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::Write {
                path: self.file(name),
                cause: e,
            }),
            _ => Ok(()),
        }
    }

    /// Make the folder `name` ready for `stage` to write `files` into it:
    /// created if missing, else emptied of what `stage` wrote there before
    /// (the record it keeps in the folder lists it) and of nothing else. A
    /// folder holding anything the record does not list, or no record at
    /// all, is the user's: refused, never deleted. The record lists `files`
    /// before any is written, so an interrupted stage's files are still
    /// known as its own.
    pub fn refill(&self, name: &str, stage: Stage, files: &[String]) -> Result<PathBuf, Error> {
        let dir = self.file(name);
        let folder = RunDir { path: dir.clone() };
        let written = folder.record()?;
        let entries = folder.entries()?;
        let foreign = entries
            .iter()
            .find(|e| e.as_str() != FOLDER_RECORD && !written.contains(e));
        if let Some(entry) = foreign {
            return Err(Error::NotOurs {
                dir,
                entry: entry.clone(),
                stage,
            });
        }
        for entry in &entries {
            folder.remove(entry)?;
        }
        std::fs::create_dir_all(&dir).map_err(|cause| Error::Write {
            path: dir.clone(),
            cause,
        })?;
        folder.write_json(FOLDER_RECORD, &files)?;
        Ok(dir)
    }

    /// Remove what `stage` wrote here, its summary first (so the stage
    /// reads as not run even if removing the rest fails): its files, and
    /// in each folder it fills the files its record lists, the folder too
    /// when nothing else is in it. Nothing else: a user's file stays.
    pub fn clear(&self, stage: Stage) -> Result<(), Error> {
        // A folder of one of the names is the user's (see `remove`).
        let ours = |name: &str| {
            self.file(name).symlink_metadata().is_ok() && !in_the_way(&self.file(name))
        };
        let summary = stage.summary_file();
        if ours(summary) {
            self.remove(summary)?;
        }
        for entry in self.entries()? {
            if stage.writes(&entry) && ours(&entry) {
                self.remove(&entry)?;
            }
        }
        for name in stage.folders() {
            let folder = RunDir {
                path: self.file(name),
            };
            if !folder.file(FOLDER_RECORD).is_file() {
                continue;
            }
            for file in folder.record()? {
                folder.remove(&file)?;
            }
            folder.remove(FOLDER_RECORD)?;
            // Fails, as it should, where the user keeps files in it.
            let _ = std::fs::remove_dir(&folder.path);
        }
        Ok(())
    }

    /// The names of the files this folder's [`FOLDER_RECORD`] lists (none
    /// without one); only plain names, so a record cannot point elsewhere.
    fn record(&self) -> Result<Vec<String>, Error> {
        if !self.file(FOLDER_RECORD).is_file() {
            return Ok(Vec::new());
        }
        let names: Vec<String> = self.read_json(FOLDER_RECORD)?;
        Ok(names
            .into_iter()
            .filter(|n| Path::new(n).file_name() == Some(std::ffi::OsStr::new(n)))
            .collect())
    }

    /// The names of the entries in this directory (none if it is missing).
    fn entries(&self) -> Result<Vec<String>, Error> {
        match std::fs::read_dir(&self.path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
            Err(cause) => Err(Error::Open {
                path: self.path.clone(),
                cause,
            }),
            Ok(entries) => entries
                .map(|e| e.map(|e| e.file_name().to_string_lossy().into_owned()))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|cause| Error::Open {
                    path: self.path.clone(),
                    cause,
                }),
        }
    }

    /// Write `name` atomically with `write`; no trace of it where writing
    /// fails. Whatever is at `name` and is not a file (a user's folder of
    /// that name) is refused, never replaced.
    pub fn write_with(
        &self,
        name: &str,
        write: impl FnOnce(&mut File) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let target = self.file(name);
        if in_the_way(&target) {
            return Err(Error::InTheWay { path: target });
        }
        let tmp = self.file(&format!(".{name}.tmp"));
        let io = |cause| Error::Write {
            path: target.clone(),
            cause,
        };
        let written = File::create(&tmp).map_err(io).and_then(|mut file| {
            write(&mut file)?;
            file.sync_all().map_err(io)?;
            std::fs::rename(&tmp, &target).map_err(io)
        });
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    }

    /// Write `name` atomically with the text `text`.
    pub fn write_text(&self, name: &str, text: &str) -> Result<(), Error> {
        let path = self.file(name);
        self.write_with(name, |f| {
            f.write_all(text.as_bytes())
                .map_err(|cause| Error::Write { path, cause })
        })
    }

    pub fn write_json(&self, name: &str, value: &impl serde::Serialize) -> Result<(), Error> {
        let text = serde_json::to_string_pretty(value).expect("JSON-serialisable");
        self.write_text(name, &(text + "\n"))
    }

    pub fn read_json<T: serde::de::DeserializeOwned>(&self, name: &str) -> Result<T, Error> {
        let path = self.file(name);
        let text = std::fs::read_to_string(&path).map_err(|cause| Error::Open {
            path: path.clone(),
            cause,
        })?;
        serde_json::from_str(&text).map_err(|e| Error::RunDir {
            path,
            why: format!("unreadable ({e}); rerun the stage that wrote it"),
        })
    }

    /// Write the Parquet table `name` (the table, or why it could not be built).
    pub fn write_table(&self, name: &str, table: PolarsResult<DataFrame>) -> Result<(), Error> {
        let path = self.file(name);
        let table_error = |cause| Error::Table {
            path: path.clone(),
            cause,
        };
        let mut df = table.map_err(table_error)?;
        self.write_with(name, |f| {
            ParquetWriter::new(f)
                .finish(&mut df)
                .map(|_| ())
                .map_err(table_error)
        })
    }

    /// Write the CSV table `name` (the table, or why it could not be built).
    pub fn write_csv(&self, name: &str, table: PolarsResult<DataFrame>) -> Result<(), Error> {
        let text = table
            .and_then(crate::outputs::csv_text)
            .map_err(|cause| Error::Table {
                path: self.file(name),
                cause,
            })?;
        self.write_text(name, &text)
    }

    /// Write the Parquet table `name` of `rows`.
    pub fn write_rows<R: Row>(&self, name: &str, rows: &[R]) -> Result<(), Error> {
        self.write_table(name, R::frame(rows))
    }

    /// Read the Parquet table `name` as rows of `R`.
    pub fn read_rows<R: Row>(&self, name: &str) -> Result<Vec<R>, Error> {
        self.read_table(name, R::rows)
    }

    /// Read the Parquet table `name` into what `parse` makes of it.
    pub fn read_table<T>(
        &self,
        name: &str,
        parse: impl FnOnce(&DataFrame) -> PolarsResult<T>,
    ) -> Result<T, Error> {
        let path = self.file(name);
        let file = File::open(&path).map_err(|cause| Error::Open {
            path: path.clone(),
            cause,
        })?;
        ParquetReader::new(file)
            .finish()
            .and_then(|df| parse(&df))
            .map_err(|cause| Error::Table { path, cause })
    }
}

/// Whether something is at `path` that postflight would not write there: a
/// folder, a device, a pipe (a link or a file is one of its own names).
fn in_the_way(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| !m.is_file() && !m.is_symlink())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_is_refilled_of_what_its_stage_wrote_and_a_users_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        let names = |n: &[&str]| n.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        // Missing: created, its record listing what will be written.
        let folder = run
            .refill("crops", Stage::Localise, &names(&["a.jpg", "b.jpg"]))
            .unwrap();
        std::fs::write(folder.join("a.jpg"), "a").unwrap();
        // Refilled: the old files go, whether or not they were all written.
        run.refill("crops", Stage::Localise, &names(&["c.jpg"]))
            .unwrap();
        assert!(!folder.join("a.jpg").exists());
        std::fs::write(folder.join("c.jpg"), "c").unwrap();
        // A file the stage did not write: refused, and everything kept.
        std::fs::write(folder.join("notes.txt"), "mine").unwrap();
        let err = run
            .refill("crops", Stage::Localise, &names(&["d.jpg"]))
            .unwrap_err()
            .to_string();
        assert!(err.contains("holds notes.txt"), "{err}");
        assert!(folder.join("c.jpg").exists() && folder.join("notes.txt").exists());
        // A folder of the same name with no record is the user's.
        std::fs::create_dir(dir.path().join("theirs")).unwrap();
        std::fs::write(dir.path().join("theirs/c.jpg"), "theirs").unwrap();
        assert!(run.refill("theirs", Stage::Localise, &[]).is_err());
        assert!(dir.path().join("theirs/c.jpg").exists());
    }

    #[test]
    fn a_stage_is_cleared_of_what_it_wrote_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        for name in [
            "replan.json",
            "replan-2.kmz",
            "replan-drone-1.csv",
            "report.html",
            "notes.txt",
        ] {
            std::fs::write(run.file(name), "x").unwrap();
        }
        let crops = run
            .refill(
                crate::outputs::localise::files::CROPS,
                Stage::Localise,
                &["a.jpg".into()],
            )
            .unwrap();
        std::fs::write(crops.join("a.jpg"), "a").unwrap();
        std::fs::write(crops.join("mine.jpg"), "mine").unwrap();
        run.clear(Stage::Replan).unwrap();
        run.clear(Stage::Localise).unwrap();
        let left = |d: &Path| {
            let mut names: Vec<String> = std::fs::read_dir(d)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        };
        assert_eq!(left(dir.path()), ["defects", "notes.txt", "report.html"]);
        // The crop it wrote goes with its record; the user's stays.
        assert_eq!(left(&crops), ["mine.jpg"]);
        std::fs::remove_file(crops.join("mine.jpg")).unwrap();
        run.refill("defects", Stage::Localise, &["b.jpg".into()])
            .unwrap();
        run.clear(Stage::Localise).unwrap();
        assert!(!crops.exists());
    }
}
