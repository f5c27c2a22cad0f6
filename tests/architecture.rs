//! ARCHITECTURE.md's table of crates and their dependencies is the one
//! `cargo metadata` reports: every workspace crate, every edge between them.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

type Edges = BTreeMap<String, BTreeSet<String>>;

/// Workspace crates and the workspace crates each depends on (any kind).
fn from_cargo() -> Edges {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(root)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let packages = meta["packages"].as_array().unwrap();
    let short = |name: &str| name.strip_prefix("postflight-").unwrap_or(name).to_string();
    let names: BTreeSet<String> = packages
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_string())
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| d["name"].as_str().unwrap())
                .filter(|d| names.contains(*d))
                .map(short)
                .collect();
            (short(p["name"].as_str().unwrap()), deps)
        })
        .collect()
}

/// The "Edge by edge" table: `| `crate` (`dir/`) | `dep` (...), ... |`.
fn from_architecture() -> Edges {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("ARCHITECTURE.md"))
            .unwrap();
    let table = &text[text.find("Edge by edge").expect("an edge table")..];
    let ticked = |cell: &str| -> Vec<String> {
        cell.split('`')
            .skip(1)
            .step_by(2)
            .filter(|t| !t.ends_with('/') && *t != ".")
            .map(|t| t.strip_prefix("postflight-").unwrap_or(t).to_string())
            .collect()
    };
    table
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .skip(2) // the header and its rule
        .take_while(|l| l.starts_with('|'))
        .map(|row| {
            let cells: Vec<&str> = row.split('|').collect();
            let krate = ticked(cells[1]).remove(0);
            let deps = if cells[2].contains("all of the above") {
                BTreeSet::from(["*".to_string()])
            } else {
                ticked(cells[2]).into_iter().collect()
            };
            (krate, deps)
        })
        .collect()
}

#[test]
fn the_architecture_table_lists_every_crate_and_every_edge_cargo_knows() {
    let cargo = from_cargo();
    let mut documented = from_architecture();
    // The binary "depends on all of the above".
    if documented.get("postflight") == Some(&BTreeSet::from(["*".to_string()])) {
        let all: BTreeSet<String> = cargo
            .keys()
            .filter(|k| *k != "postflight")
            .cloned()
            .collect();
        documented.insert("postflight".into(), all);
    }
    assert_eq!(documented, cargo);
}
