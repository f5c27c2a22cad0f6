//! `--help` for settings: each setting's flag ends with its default, taken
//! from the settings' own declaration (`Settings::default().resolve()`), so
//! a default is written once.

use crate::config::{Table, tables};

/// `cli` with every stage command's setting flags ending in their defaults.
pub fn with_defaults(mut cli: clap::Command) -> clap::Command {
    let tables = tables();
    let names: Vec<String> = cli
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    for name in names {
        cli = cli.mut_subcommand(name, |mut command| {
            let taken: Vec<&Table> = tables.iter().filter(|t| takes(&command, t)).collect();
            for table in taken {
                for (id, default) in defaults(table) {
                    command = command.mut_arg(id, |arg| {
                        let help = arg.get_help().map(|h| h.to_string()).unwrap_or_default();
                        arg.help(format!("{help} [default: {default}]"))
                    });
                }
            }
            command
        });
    }
    cli
}

/// Whether `command` has the table's flags (flattened from its settings).
fn takes(command: &clap::Command, table: &Table) -> bool {
    table.args.get_arguments().all(|flag| {
        command
            .get_arguments()
            .any(|a| a.get_id() == flag.get_id() && a.get_long() == flag.get_long())
    })
}

/// The table's flags with a default, and the default as help shows it.
fn defaults(table: &Table) -> Vec<(String, String)> {
    table
        .args
        .get_arguments()
        .filter_map(|arg| {
            let id = arg.get_id().to_string();
            let text = value_text(&table.defaults[&id])?;
            let text = match table.default_from {
                Some(from) => format!("{from} {text}"),
                None => text,
            };
            Some((id, text))
        })
        .collect()
}

/// docs/cli.md's settings reference: a table per `postflight.toml` table,
/// each key with its flag, its default and the first line of its doc, all
/// from the declarations (a test keeps docs/cli.md's copy equal to it).
#[cfg(test)]
pub fn reference() -> String {
    let mut out = String::new();
    for table in tables() {
        out.push_str(&format!(
            "\n### `[{}]`\n\n| key | flag | default | what |\n|---|---|---|---|\n",
            table.name
        ));
        let defaults: std::collections::BTreeMap<String, String> =
            defaults(&table).into_iter().collect();
        for arg in table.args.get_arguments() {
            let id = arg.get_id().to_string();
            let help = arg.get_help().map(|h| h.to_string()).unwrap_or_default();
            let cell = |text: &str| text.replace('|', "\\|");
            out.push_str(&format!(
                "| `{id}` | `--{}` | {} | {} |\n",
                arg.get_long().unwrap_or_default(),
                defaults.get(&id).map_or(String::new(), |d| cell(d)),
                cell(help.lines().next().unwrap_or_default()),
            ));
        }
    }
    out
}

/// A default as typed on the command line; `None` for none (null, empty).
fn value_text(value: &serde_json::Value) -> Option<String> {
    use serde_json::Value;
    match value {
        Value::Null => None,
        Value::String(s) => Some(s.clone()),
        Value::Array(items) if items.is_empty() => None,
        Value::Array(items) => items
            .iter()
            .map(value_text)
            .collect::<Option<Vec<_>>>()
            .map(|v| v.join(",")),
        // Shortest form: 0.2 for an f32's 0.2, 1 for 1.0 (as clap shows defaults).
        Value::Number(n) => Some(match n.as_f64() {
            Some(x) if n.is_f64() && f64::from(x as f32) == x => (x as f32).to_string(),
            Some(x) if n.is_f64() => x.to_string(),
            _ => n.to_string(),
        }),
        Value::Bool(b) => Some(b.to_string()),
        Value::Object(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    /// Where docs/cli.md's settings reference starts and ends.
    const BEGIN: &str = "<!-- settings reference: generated from the declarations; the test the_settings_reference_in_docs_is_the_declarations rewrites it when run with POSTFLIGHT_BLESS=1 -->\n";
    const END: &str = "<!-- end of the settings reference -->";

    #[test]
    fn the_settings_reference_in_docs_is_the_declarations() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/cli.md");
        let docs = std::fs::read_to_string(path).unwrap();
        let (start, end) = (
            docs.find(BEGIN)
                .expect("docs/cli.md has the settings reference")
                + BEGIN.len(),
            docs.find(END)
                .expect("docs/cli.md ends the settings reference"),
        );
        let generated = super::reference();
        if std::env::var_os("POSTFLIGHT_BLESS").is_some() {
            let text = format!("{}{generated}\n{}", &docs[..start], &docs[end..]);
            std::fs::write(path, text).unwrap();
            return;
        }
        assert_eq!(
            docs[start..end].trim(),
            generated.trim(),
            "docs/cli.md's settings reference differs from the declarations: rerun with POSTFLIGHT_BLESS=1"
        );
    }

    #[test]
    fn help_shows_each_default_as_declared() {
        let mut cli = super::with_defaults(crate::Cli::command());
        let help = |cli: &mut clap::Command, name: &str| {
            cli.find_subcommand_mut(name)
                .unwrap()
                .render_help()
                .to_string()
        };
        let detect = help(&mut cli, "detect");
        assert!(detect.contains("[default: 0.25]"), "{detect}");
        assert!(detect.contains("[default: crack]"), "{detect}");
        let coverage = help(&mut cli, "coverage");
        assert!(
            coverage.contains("[default: the plan's, else 5]"),
            "{coverage}"
        );
        let gtsp = help(&mut cli, "gtsp");
        assert_eq!(gtsp.matches("[default: 1]").count(), 1, "{gtsp}");
    }
}
