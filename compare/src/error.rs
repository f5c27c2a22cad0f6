//! Why two runs could not be compared, each saying what to do.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error("cannot register {} onto {}: {cause}", before.display(), after.display())]
    Register {
        before: PathBuf,
        after: PathBuf,
        cause: postflight_core::map::register::RegisterError,
    },
    #[error(transparent)]
    Ingest(#[from] ingest::IngestError),
    #[error(transparent)]
    Coverage(#[from] coverage::CoverageError),
    #[error(transparent)]
    Core(#[from] postflight_core::Error),
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
}
