//! How errors word a setting: as the flag the user typed, or as the key of
//! the config file that set it. Libraries name settings by their key in
//! `postflight.toml` (`[detect] image_size`); the same setting is `--imgsz`
//! to `postflight detect`. Set once at start-up, from the parsed command
//! line and the config file it names.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use clap::parser::ValueSource;
use clap::{ArgMatches, CommandFactory};
use postflight_core::Key;

use crate::config::RunConfig;

/// A setting's flag, as its settings struct declares it.
fn flag_of(table: &str, name: &str) -> Option<String> {
    let tables = crate::config::tables();
    let table = tables.iter().find(|t| t.name == table)?;
    table
        .args
        .get_arguments()
        .find(|arg| arg.get_id() == name)
        .and_then(|arg| arg.get_long())
        .map(|long| format!("--{long}"))
}

/// What one invocation can tell about where each setting came from.
#[derive(Debug, Default)]
pub struct Sources {
    /// Flags the invoked command has.
    flags: BTreeSet<String>,
    /// Flags given on the command line.
    given: BTreeSet<String>,
    /// The config file, with the `(table, key)`s it sets.
    config: Option<(PathBuf, BTreeSet<(String, String)>)>,
    /// Where a config file would be given, when none is: `--config` unless
    /// the command takes it from elsewhere.
    config_source: Option<&'static str>,
}

impl Sources {
    /// The invoked (sub)command's flags and those given, from `matches` of
    /// the whole command line.
    pub fn of(matches: &ArgMatches) -> Self {
        let mut command = crate::Cli::command();
        let mut matches = matches;
        while let Some((name, sub)) = matches.subcommand() {
            command = command
                .find_subcommand(name)
                .cloned()
                .expect("a parsed subcommand exists");
            matches = sub;
        }
        let given = command
            .get_arguments()
            .filter(|arg| {
                matches.value_source(arg.get_id().as_str()) == Some(ValueSource::CommandLine)
            })
            .filter_map(|arg| arg.get_long().map(|long| format!("--{long}")))
            .collect();
        Self {
            flags: flags_of(&command),
            given,
            config: None,
            config_source: None,
        }
    }

    /// Where this command takes its config file from (`the manifest's
    /// `config` column`), for settings no config file was given for.
    pub fn with_config_source(mut self, source: &'static str) -> Self {
        self.config_source = Some(source);
        self
    }

    /// The config file in use, and what it sets.
    pub fn with_config(mut self, path: &Path, config: &RunConfig) -> Self {
        self.config = Some((path.to_owned(), config.keys_set()));
        self
    }

    /// How to word `key` for this invocation; `None` leaves the default.
    pub fn word(&self, key: &Key) -> Option<String> {
        let Key::Setting { table, name } = *key else {
            return None;
        };
        let flag = flag_of(table, name).filter(|f| self.flags.contains(f));
        let in_config = self
            .config
            .as_ref()
            .filter(|(_, set)| set.contains(&(table.to_string(), name.to_string())));
        match (flag, in_config) {
            (Some(flag), Some(_)) if self.given.contains(&flag) => Some(flag),
            (_, Some((path, _))) => Some(format!("[{table}] {name} in {}", path.display())),
            (Some(flag), None) => Some(flag),
            (None, None) => match &self.config {
                Some((path, _)) => Some(format!("[{table}] {name} in {}", path.display())),
                None => Some(format!(
                    "[{table}] {name} of {}",
                    self.config_source.unwrap_or("a --config file")
                )),
            },
        }
    }

    /// Word keys so for the rest of the process.
    pub fn install(self) {
        postflight_core::setting::word_keys_with(move |key| self.word(key));
    }
}

/// The long flags of a command.
fn flags_of(command: &clap::Command) -> BTreeSet<String> {
    command
        .get_arguments()
        .filter_map(|arg| arg.get_long().map(|long| format!("--{long}")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::FromArgMatches;

    fn sources(args: &[&str]) -> Sources {
        let matches = crate::Cli::command().try_get_matches_from(args).unwrap();
        crate::Cli::from_arg_matches(&matches).unwrap();
        Sources::of(&matches)
    }

    #[test]
    fn every_setting_is_a_flag_of_its_stage_command() {
        let cli = crate::Cli::command();
        for (table, name) in RunConfig::default().keys() {
            let flag = flag_of(&table, &name).unwrap_or_else(|| panic!("[{table}] {name}"));
            let commands: &[&str] = match table.as_str() {
                "view" => &["localise", "coverage"],
                "condition" => &["localise"],
                t => &[t],
            };
            for command in commands {
                let flags = flags_of(cli.find_subcommand(command).unwrap());
                assert!(flags.contains(&flag), "postflight {command} has no {flag}");
            }
        }
    }

    #[test]
    fn a_setting_is_worded_as_the_user_gave_it() {
        let key = detect::settings::keys::image_size;
        let detect = sources(&["postflight", "detect", "--run", "r", "--model", "m"]);
        assert_eq!(detect.word(&key).unwrap(), "--imgsz");
        let run = sources(&["postflight", "run", "--flight", "f", "--out", "o"]);
        assert_eq!(
            run.word(&key).unwrap(),
            "[detect] image_size of a --config file"
        );
        let config: RunConfig = toml::from_str("[detect]\nimage_size = 33\n").unwrap();
        let run = run.with_config(Path::new("run.toml"), &config);
        assert_eq!(run.word(&key).unwrap(), "[detect] image_size in run.toml");
        // A flag given beats the config file; a setting the file leaves
        // alone is the flag's.
        let config: RunConfig = toml::from_str("[view]\nmax_distance_m = 4.0\n").unwrap();
        let coverage = sources(&[
            "postflight",
            "coverage",
            "--run",
            "r",
            "--max-distance",
            "3",
        ])
        .with_config(Path::new("c.toml"), &config);
        let max = postflight_core::view::keys::max_distance_m;
        assert_eq!(coverage.word(&max).unwrap(), "--max-distance");
        let min = postflight_core::view::keys::min_distance_m;
        assert_eq!(coverage.word(&min).unwrap(), "--min-distance");
        assert_eq!(coverage.word(&postflight_core::setting::inputs::MAP), None);
        // A key set to what JSON cannot hold (NaN, infinity) is still set.
        let config: RunConfig = toml::from_str("[replan]\nspeed_m_s = nan\n").unwrap();
        let replan = sources(&["postflight", "replan", "--run", "r"])
            .with_config(Path::new("n.toml"), &config);
        let speed = replan::settings::keys::speed_m_s;
        assert_eq!(replan.word(&speed).unwrap(), "[replan] speed_m_s in n.toml");
    }
}
