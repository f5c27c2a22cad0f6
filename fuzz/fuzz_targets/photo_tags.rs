//! A photo's EXIF and XMP (DJI's drone-dji) tags, as ingest reads them.
#![no_main]
libfuzzer_sys::fuzz_target!(|jpeg: &[u8]| {
    let _ = ingest::photos::read_tags(jpeg);
});
