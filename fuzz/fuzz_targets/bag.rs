//! A ROS 1 bag, scanned for its connections, messages and chunks.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let _ = ingest::bag::scan(bytes, |_| {});
});
