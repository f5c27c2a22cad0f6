//! Why a record could not be made, each saying what to do.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error(
        "[record] not_inspected = \"previous\" takes the missed parts' states from an earlier record: give --previous RUN (a run with elements.parquet), or choose not_inspected = \"cs1\" or \"refuse\""
    )]
    NoPrevious,
    #[error(
        "the earlier record in {} has no row for element {element:?} (AASHTO {number}), which this flight did not wholly inspect; give an earlier run of the same structure, or choose [record] not_inspected = \"cs1\" or \"refuse\"", run.display()
    )]
    PreviousLacks {
        run: PathBuf,
        element: String,
        number: u16,
    },
    #[error(
        "the record in {} cannot be remade from its record.json ({why}); run `postflight record --run` on it again", run.display()
    )]
    Unreadable { run: PathBuf, why: String },
    #[error(transparent)]
    Core(#[from] postflight_core::Error),
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
}
