//! The run directory's file contract: for every stage, the files it writes,
//! its JSON summary and one typed writer and reader per table. A stage's
//! summary is written last, so a stage is complete exactly when its summary
//! exists ([`RunDir::open`](crate::RunDir::open) checks it).

pub mod coverage;
pub mod detect;
pub mod ingest;
pub mod localise;
pub mod replan;
pub mod report;

/// The pipeline's stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Stage {
    Ingest,
    Detect,
    Localise,
    Coverage,
    Replan,
    Report,
}

impl Stage {
    pub const ALL: [Self; 6] = [
        Self::Ingest,
        Self::Detect,
        Self::Localise,
        Self::Coverage,
        Self::Replan,
        Self::Report,
    ];

    /// Its name, as its command (`postflight localise`) and `pipeline.json` spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ingest => "ingest",
            Self::Detect => "detect",
            Self::Localise => "localise",
            Self::Coverage => "coverage",
            Self::Replan => "replan",
            Self::Report => "report",
        }
    }

    /// The file it writes last: it exists exactly when the stage completed.
    pub fn summary_file(self) -> &'static str {
        match self {
            Self::Ingest => ingest::files::SUMMARY,
            Self::Detect => detect::files::SUMMARY,
            Self::Localise => localise::files::SUMMARY,
            Self::Coverage => coverage::files::SUMMARY,
            Self::Replan => replan::files::SUMMARY,
            Self::Report => report::files::SUMMARY,
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
