//! An MCAP recording, scanned for its topics, messages and chunks.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let _ = ingest::recording::scan_mcap(bytes, |_| {});
});
