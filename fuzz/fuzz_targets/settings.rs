//! A `postflight.toml`: each stage's table as its stage reads it.
#![no_main]
use toml::{Table, Value};

fn stage<T: serde::de::DeserializeOwned>(file: &Table, name: &str) -> Option<T> {
    file.get(name)
        .cloned()
        .and_then(|t| Value::try_into(t).ok())
}

libfuzzer_sys::fuzz_target!(|text: &str| {
    let Ok(file) = toml::from_str::<Table>(text) else {
        return;
    };
    let _ = stage::<ingest::IngestSettings>(&file, "ingest");
    let _ = stage::<detect::DetectSettings>(&file, "detect");
    let _ = stage::<localise::LocaliseSettings>(&file, "localise");
    let _ = stage::<coverage::CoverageSettings>(&file, "coverage");
    if let Some(settings) = stage::<postflight_core::ViewSettings>(&file, "view") {
        let _ = settings.resolve().check();
    }
    if let Some(settings) =
        stage::<postflight_core::condition::ConditionSettings>(&file, "condition")
    {
        let _ = settings.resolve().check();
    }
    if let Some(settings) = stage::<compare::CompareSettings>(&file, "compare") {
        let _ = settings.resolve().check();
    }
    if let Some(settings) = stage::<replan::ReplanSettings>(&file, "replan") {
        let _ = settings.resolve();
    }
    if let Some(settings) = stage::<record::RecordSettings>(&file, "record") {
        let _ = settings.resolve().check();
    }
});
