//! The run directory's file contract: for every stage, the files it writes,
//! its JSON summary and one typed writer and reader per table. A stage's
//! summary is written last, so a stage is complete exactly when its summary
//! exists ([`RunDir::open`](crate::RunDir::open) checks it).

use polars::prelude::{
    CsvWriter, DataFrame, DataType, IntoSeries, PlSmallStr, PolarsResult, SerWriter,
};

pub mod changes;
pub mod coverage;
pub mod detect;
pub mod ingest;
pub mod localise;
pub mod record;
pub mod replan;
pub mod report;

/// The pipeline's stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, clap::ValueEnum)]
pub enum Stage {
    Ingest,
    Detect,
    Localise,
    Coverage,
    Replan,
    Record,
    Report,
}

impl Stage {
    pub const ALL: [Self; 7] = [
        Self::Ingest,
        Self::Detect,
        Self::Localise,
        Self::Coverage,
        Self::Replan,
        Self::Record,
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
            Self::Record => "record",
            Self::Report => "report",
        }
    }

    /// Whether `name`, a file in the run directory, is one it writes.
    pub fn writes(self, name: &str) -> bool {
        let named = |names: &[&str]| names.contains(&name);
        match self {
            Self::Ingest => {
                use ingest::files::*;
                named(&[FRAMES, TRAJECTORY, CAMERAS, GNSS, SUMMARY])
            }
            Self::Detect => {
                use detect::files::*;
                named(&[DETECTIONS, COCO, SUMMARY]) || detect::Shard::of_file(name).is_some()
            }
            Self::Localise => {
                use localise::files::*;
                named(&[OBSERVATIONS, DEFECTS, DEFECTS_JSON, SUMMARY])
            }
            Self::Coverage => {
                use coverage::files::*;
                named(&[TABLE, SUMMARY, VIEWPOINTS_TABLE, VIEWPOINTS_SUMMARY])
            }
            Self::Replan => {
                use replan::files::*;
                named(&[SUMMARY, PATH_CSV, KML, GEOJSON])
                    || is_mission(name)
                    || is_drone_path_csv(name)
            }
            Self::Record => {
                use record::files::*;
                named(&[ELEMENTS, NBE_XML, SNBI_JSON, SUMMARY])
            }
            Self::Report => {
                use report::files::*;
                named(&[REPORT, CANDIDATES, RECORDING, SUMMARY])
            }
        }
    }

    /// The folders it fills, each keeping a record of what it wrote there
    /// ([`RunDir::refill`](crate::RunDir::refill)).
    pub fn folders(self) -> &'static [&'static str] {
        match self {
            Self::Localise => &[localise::files::CROPS],
            _ => &[],
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
            Self::Record => record::files::SUMMARY,
            Self::Report => report::files::SUMMARY,
        }
    }
}

/// A table as CSV text: a header line, RFC 4180 quoting, missing values
/// empty, and text a spreadsheet would run as a formula made inert
/// ([`inert`]).
pub fn csv_text(mut table: DataFrame) -> PolarsResult<String> {
    let text_columns: Vec<PlSmallStr> = table
        .columns()
        .iter()
        .filter(|c| c.dtype() == &DataType::String)
        .map(|c| c.name().clone())
        .collect();
    for name in text_columns {
        let safe = table
            .column(name.as_str())?
            .str()?
            .apply_into_string_amortized(|text, out| out.push_str(&inert(text)));
        table.replace(name.as_str(), safe.into_series().into())?;
    }
    let mut out = Vec::new();
    CsvWriter::new(&mut out).finish(&mut table)?;
    Ok(String::from_utf8(out).expect("polars writes UTF-8 CSV"))
}

/// A text cell as a spreadsheet shows it, never runs it: text starting with
/// `=`, `@`, a tab or a carriage return, or with `+` or `-` and holding more
/// than letters, digits, `_`, `.`, `+`, `-` and spaces (which could call a
/// function), gets a leading `'` (OWASP's advice on CSV injection). Ids and
/// signed numbers stay as they are.
pub fn inert(text: &str) -> std::borrow::Cow<'_, str> {
    let plain = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '+' | '-' | ' ');
    let runs = match text.chars().next() {
        Some('=' | '@' | '\t' | '\r') => true,
        Some('+' | '-') => !text.chars().all(plain),
        _ => false,
    };
    if runs {
        format!("'{text}").into()
    } else {
        text.into()
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use polars::prelude::*;

    use super::*;

    #[test]
    fn formulas_are_made_inert_and_ids_and_numbers_kept() {
        let cases = [
            (
                "=HYPERLINK(\"http://x\",\"y\")",
                "'=HYPERLINK(\"http://x\",\"y\")",
            ),
            ("@SUM(A1)", "'@SUM(A1)"),
            ("+cmd|' /C calc'!A0", "'+cmd|' /C calc'!A0"),
            ("-2+3*cmd|x", "'-2+3*cmd|x"),
            ("\t=1", "'\t=1"),
            ("\r=1", "'\r=1"),
            ("-12_3_4+x", "-12_3_4+x"),
            ("-1.5", "-1.5"),
            ("a = b", "a = b"),
            ("", ""),
        ];
        for (text, shown) in cases {
            assert_eq!(inert(text), shown, "{text:?}");
        }
        let table = df!("note" => ["=1+1", "fine"], "x" => [-1.0, 2.0]).unwrap();
        assert_eq!(csv_text(table).unwrap(), "note,x\n'=1+1,-1.0\nfine,2.0\n");
    }
}
