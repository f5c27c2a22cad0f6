//! A survey's LAS or LAZ file: header, VLRs (its CRS) and points.
#![no_main]

static DEFAULT_HOOK: std::sync::Once = std::sync::Once::new();

libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    // The parser catches the LAZ decoder's assertions on corrupt streams;
    // libfuzzer-sys's hook would abort on them before they are caught. A
    // panic the parser does not catch still aborts (libfuzzer-sys catches
    // it at the target's edge).
    DEFAULT_HOOK.call_once(|| drop(std::panic::take_hook()));
    let _ = postflight_core::map::las::parse(bytes);
});
