//! What a model's custom metadata tells: its stride and its class names, as
//! Ultralytics writes them.

use std::collections::HashMap;

/// The model's custom metadata, keys as written.
pub(crate) fn metadata(session: &ort::session::Session) -> HashMap<String, String> {
    let Ok(meta) = session.metadata() else {
        return HashMap::new();
    };
    meta.custom_keys()
        .unwrap_or_default()
        .into_iter()
        .filter_map(|k| Some((k.clone(), meta.custom(&k)?)))
        .collect()
}

/// The model's stride from its metadata (Ultralytics writes `stride`).
pub(crate) fn model_stride(metadata: &HashMap<String, String>) -> Option<u32> {
    let stride = metadata.get("stride")?;
    stride.trim().parse().ok().filter(|s| *s > 0)
}

/// The long side, pixels, of the photos an area model was trained on
/// (postflight's area model writes `postflight.train_px`): it runs a frame
/// scaled to that.
pub(crate) fn train_px(metadata: &HashMap<String, String>) -> Option<u32> {
    let px = metadata.get("postflight.train_px")?;
    px.trim().parse().ok().filter(|p| (32..=8192).contains(p))
}

/// Class names of a model with a baked vocabulary, from its `names` metadata
/// (Ultralytics writes `{0: 'crack', 1: 'spalling'}`).
pub(crate) fn baked_names(metadata: &HashMap<String, String>) -> Option<Vec<String>> {
    let names = metadata.get("names")?;
    let mut out = Vec::new();
    for entry in names
        .trim()
        .trim_start_matches('{')
        .trim_end_matches('}')
        .split(',')
    {
        let (_, name) = entry.split_once(':')?;
        out.push(
            name.trim()
                .trim_matches(|c| c == '\'' || c == '"')
                .to_string(),
        );
    }
    Some(out)
}
