//! Reading a flight recording record by record, tolerant of the damage real
//! flights have: a file cut off mid-chunk (battery died, card pulled) and
//! chunks whose bytes are corrupt.
//!
//! The file is memory-mapped and walked once, front to back. Uncompressed
//! chunks are read in place, so metadata ingest touches only the bytes it
//! decodes. Every message carries a [`MessageLocation`] so a later stage can
//! fetch just that message again ([`Recording::read_message`]) without
//! holding the flight in memory.

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use mcap::records::op;

use postflight_core::frame::MessageLocation;

use crate::error::IngestError;

/// A channel (topic) of the recording with its schema.
#[derive(Debug, Clone)]
pub struct Channel {
    pub id: u16,
    pub topic: String,
    /// Schema name, e.g. `sensor_msgs/msg/Image`; empty when the channel has none.
    pub schema: String,
    /// Schema encoding, e.g. `ros2msg`.
    pub schema_encoding: String,
    /// Message encoding, e.g. `cdr`.
    pub message_encoding: String,
    /// The schema's text: the message definition (`.msg` text with its
    /// dependencies) for `ros2msg` and `ros1msg` schemas.
    pub definition: String,
}

/// One message as met during a scan; `data` borrows the mapped file or the
/// current chunk's decompressed buffer.
#[derive(Debug, Clone, Copy)]
pub struct RecordedMessage<'a> {
    pub channel_id: u16,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: &'a [u8],
    pub location: MessageLocation,
}

/// What a scan met, passed to the scan's visitor in file order.
#[derive(Debug)]
pub enum ScanEvent<'a> {
    /// A channel became known (its schema is resolved if it was recorded).
    Channel(&'a Channel),
    Message(RecordedMessage<'a>),
    /// `bytes` of the file have been walked so far.
    Progress {
        bytes: u64,
    },
}

/// Damage and extent of a recording, as found by [`Recording::scan`].
#[derive(Debug, Clone, Default)]
pub struct ScanReport {
    /// The file ends before its data-end record and closing magic.
    pub truncated: bool,
    /// File offset where readable data stopped, when truncated.
    pub truncated_at: Option<u64>,
    /// Chunks skipped because their bytes are damaged.
    pub corrupt_chunks: u64,
    /// One line per damaged chunk or record: where and why.
    pub problems: Vec<String>,
}

/// The container a recording is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Container {
    /// MCAP, with ROS 2 (`cdr`) or ROS 1 (`ros1`) messages.
    Mcap,
    /// A ROS 1 bag, format 2.0 ([`crate::bag`]).
    Bag,
}

/// A memory-mapped flight recording: MCAP or a ROS 1 bag.
pub struct Recording {
    path: PathBuf,
    map: memmap2::Mmap,
    container: Container,
    /// The most recently decompressed chunk, for sequential `read_message` calls.
    chunk_cache: Mutex<Option<(u64, Vec<u8>)>>,
    /// How the topics later stages read again decode ([`Recording::reopen`]).
    pub(crate) wires: HashMap<String, crate::ros::Wire>,
    /// The map's pages below this offset were handed back
    /// ([`Recording::release_before`]).
    released: AtomicUsize,
}

const RECORD_PREFIX: usize = 9; // opcode u8 + length u64

/// Readers going front to back hand back the pages they have left this
/// far behind them...
const RELEASE_LAG: usize = 64 << 20;
/// ...this much at a time.
const RELEASE_STEP: usize = 32 << 20;

impl Recording {
    /// Open and map `path`, checking it is an MCAP file or a ROS 1 bag.
    pub fn open(path: &Path) -> Result<Self, IngestError> {
        // Before opening: opening a named pipe waits for a writer for ever.
        match std::fs::metadata(path) {
            Err(cause) => {
                return Err(postflight_core::Error::Open {
                    path: path.to_owned(),
                    cause,
                }
                .into());
            }
            Ok(_) => {
                postflight_core::user_file::check(path).map_err(|e| IngestError::NotRecording {
                    path: path.to_owned(),
                    why: e.to_string(),
                })?
            }
        }
        let file = File::open(path).map_err(|cause| postflight_core::Error::Open {
            path: path.to_owned(),
            cause,
        })?;
        // SAFETY: the map is read-only; a file changed underneath us by another
        // process is outside what a post-flight tool can defend against.
        let map =
            unsafe { memmap2::Mmap::map(&file) }.map_err(|cause| postflight_core::Error::Open {
                path: path.to_owned(),
                cause,
            })?;
        #[cfg(unix)]
        let _ = map.advise(memmap2::Advice::Sequential);
        let container = if map.starts_with(mcap::MAGIC) {
            Container::Mcap
        } else if map.starts_with(crate::bag::MAGIC) {
            Container::Bag
        } else {
            let why = if map.is_empty() {
                "it is empty".to_string()
            } else if map.starts_with(b"#ROSBAG") {
                "it is a ROS bag of a format other than 2.0".to_string()
            } else {
                "it starts with neither the MCAP magic bytes nor `#ROSBAG V2.0`".to_string()
            };
            return Err(IngestError::NotRecording {
                path: path.to_owned(),
                why,
            });
        };
        Ok(Self {
            path: path.to_owned(),
            map,
            container,
            chunk_cache: Mutex::new(None),
            wires: HashMap::new(),
            released: AtomicUsize::new(0),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether a file is named as a recording: `.mcap` or `.bag`.
    pub fn is_recording_name(path: &Path) -> bool {
        let extension = path.extension().and_then(|e| e.to_str());
        extension.is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("bag"))
    }

    /// File size in bytes.
    pub fn len(&self) -> u64 {
        self.map.len() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// Walk the whole recording once, calling `visit` for every channel and
    /// message in file order. Damage is recorded in the report, never fatal.
    pub fn scan(&self, mut visit: impl FnMut(ScanEvent<'_>)) -> ScanReport {
        let visit = |event: ScanEvent<'_>| {
            if let ScanEvent::Progress { bytes } = event {
                self.release_before(bytes as usize);
            }
            visit(event)
        };
        match self.container {
            Container::Mcap => scan_mcap(&self.map, visit),
            Container::Bag => crate::bag::scan(&self.map, visit),
        }
    }

    /// Hands back the map's pages more than [`RELEASE_LAG`] below `offset`,
    /// where a reader going front to back has got to. The kernel keeps them
    /// in its page cache, but they stop counting as this process's memory:
    /// a flight of many gigabytes is read in bounded resident memory. A
    /// page read again is simply mapped again.
    fn release_before(&self, offset: usize) {
        let to = offset.saturating_sub(RELEASE_LAG);
        let from = self.released.load(Ordering::Relaxed);
        if to < from {
            // Going back (another pass): the pages from here on may be mapped
            // again, and are handed back again as the reader passes them.
            let _ = self
                .released
                .compare_exchange(from, to, Ordering::Relaxed, Ordering::Relaxed);
            return;
        }
        if to < from + RELEASE_STEP
            || self
                .released
                .compare_exchange(from, to, Ordering::Relaxed, Ordering::Relaxed)
                .is_err()
        {
            return;
        }
        // SAFETY: the map is a read-only file mapping, so MADV_DONTNEED drops
        // only this process's view of the pages; reading them again reads the
        // file's same bytes. Nothing is ever written through the map.
        #[cfg(unix)]
        let _ = unsafe {
            self.map
                .unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, from, to - from)
        };
    }

    /// Fetch the payload of one message found by an earlier scan.
    pub fn read_message(&self, location: MessageLocation) -> Result<Vec<u8>, IngestError> {
        let bad = |why: &str| IngestError::BadLocation {
            path: self.path.clone(),
            location,
            why: why.to_string(),
        };
        let buf: &[u8] = &self.map;
        self.release_before(location.chunk_offset.unwrap_or(location.record_offset) as usize);
        if self.container == Container::Bag {
            let mut cache = self.chunk_cache.lock().unwrap_or_else(|e| e.into_inner());
            return crate::bag::read_message(buf, location, &mut cache).map_err(|e| bad(&e));
        }
        let fetch = |records: &[u8]| message_payload(records, location).map_err(bad);
        let Some(chunk_offset) = location.chunk_offset else {
            return fetch(buf);
        };
        let (opcode, chunk) =
            record_at(buf, chunk_offset as usize).ok_or_else(|| bad("chunk past the end"))?;
        if opcode != op::CHUNK {
            return Err(bad("not a chunk record"));
        }
        let mut cache = self.chunk_cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((offset, records)) = cache.as_ref()
            && *offset == chunk_offset
        {
            return fetch(records);
        }
        let mut decompressed = Vec::new();
        match open_chunk(chunk, &mut decompressed).map_err(|e| bad(&e))? {
            // Uncompressed chunks are read in place; nothing to cache.
            Records::InPlace(range) => fetch(&chunk[range]),
            Records::InBuffer => {
                let result = fetch(&decompressed);
                *cache = Some((chunk_offset, decompressed));
                result
            }
        }
    }
}

/// Walk an MCAP file held in memory once, calling `visit` for every
/// channel and message in file order (as [`Recording::scan`] does).
pub fn scan_mcap(buf: &[u8], mut visit: impl FnMut(ScanEvent<'_>)) -> ScanReport {
    let mut report = ScanReport::default();
    let mut links = ChannelLinks::default();
    let mut chunks = ChunkBatch::new();
    let mut pos = mcap::MAGIC.len();
    let mut last_progress = 0usize;
    let mut ended = false;
    while pos < buf.len() {
        if pos - last_progress >= 4 << 20 {
            visit(ScanEvent::Progress { bytes: pos as u64 });
            last_progress = pos;
        }
        let Some((opcode, body)) = record_at(buf, pos) else {
            chunks.flush(&mut links, &mut visit, &mut report);
            let partial = &buf[pos..];
            if partial.first() == Some(&op::CHUNK) && partial.len() > RECORD_PREFIX {
                salvage_partial_chunk(
                    pos as u64,
                    &partial[RECORD_PREFIX..],
                    &mut links,
                    &mut visit,
                    &mut report,
                );
            }
            report.truncated = true;
            report.truncated_at = Some(pos as u64);
            break;
        };
        if opcode == op::CHUNK {
            chunks.push(pos, body);
            if chunks.is_full() {
                chunks.flush(&mut links, &mut visit, &mut report);
            }
            pos += RECORD_PREFIX + body.len();
            continue;
        }
        // Records outside chunks come after the chunks before them.
        chunks.flush(&mut links, &mut visit, &mut report);
        match opcode {
            op::SCHEMA | op::CHANNEL => {
                if let Err(e) = links.add(opcode, body, &mut visit) {
                    report
                        .problems
                        .push(format!("record at byte {pos}: {e}; skipped"));
                }
            }
            op::MESSAGE => {
                let location = MessageLocation {
                    chunk_offset: None,
                    record_offset: pos as u64,
                };
                if let Some(message) = parse_message(body, location) {
                    visit(ScanEvent::Message(message));
                } else {
                    report.problems.push(format!(
                        "message record at byte {pos} is malformed; skipped"
                    ));
                }
            }
            op::DATA_END => {
                // The summary section repeats what the data section held;
                // a complete file ends with the magic bytes.
                ended = true;
                break;
            }
            _ => {}
        }
        pos += RECORD_PREFIX + body.len();
    }
    chunks.flush(&mut links, &mut visit, &mut report);
    let complete = ended && buf.ends_with(mcap::MAGIC);
    if !report.truncated && !complete {
        report.truncated = true;
        report.truncated_at = Some(pos.min(buf.len()) as u64);
    }
    visit(ScanEvent::Progress {
        bytes: buf.len() as u64,
    });
    report
}

/// Complete chunks waiting to be decompressed and checked together, in
/// parallel, then emitted in file order.
struct ChunkBatch<'a> {
    chunks: Vec<(usize, &'a [u8])>,
    /// One decompression buffer per batch slot, reused across batches.
    buffers: Vec<Vec<u8>>,
}

impl<'a> ChunkBatch<'a> {
    const SIZE: usize = 16;

    fn new() -> Self {
        Self {
            chunks: Vec::with_capacity(Self::SIZE),
            buffers: (0..Self::SIZE).map(|_| Vec::new()).collect(),
        }
    }

    fn push(&mut self, pos: usize, body: &'a [u8]) {
        self.chunks.push((pos, body));
    }

    fn is_full(&self) -> bool {
        self.chunks.len() == Self::SIZE
    }

    fn flush(
        &mut self,
        links: &mut ChannelLinks,
        visit: &mut impl FnMut(ScanEvent<'_>),
        report: &mut ScanReport,
    ) {
        use rayon::prelude::*;
        let opened: Vec<Result<Records, String>> = self
            .chunks
            .par_iter()
            .zip(self.buffers.par_iter_mut())
            .map(|((_, body), out)| open_chunk(body, out))
            .collect();
        for (((pos, body), out), opened) in self.chunks.iter().zip(&self.buffers).zip(opened) {
            let records = match &opened {
                Ok(Records::InPlace(range)) => Ok(&body[range.clone()]),
                Ok(Records::InBuffer) => Ok(out.as_slice()),
                Err(e) => Err(e.clone()),
            };
            if let Err(e) =
                records.and_then(|records| walk_records(records, *pos as u64, links, visit))
            {
                report.corrupt_chunks += 1;
                report
                    .problems
                    .push(format!("chunk at byte {pos}: {e}; skipped"));
            }
        }
        self.chunks.clear();
    }
}

/// The payload of the message record at `location.record_offset` of `records`.
fn message_payload(records: &[u8], location: MessageLocation) -> Result<Vec<u8>, &'static str> {
    let (opcode, body) =
        record_at(records, location.record_offset as usize).ok_or("record past the end")?;
    if opcode != op::MESSAGE {
        return Err("not a message record");
    }
    let m = parse_message(body, location).ok_or("malformed message")?;
    Ok(m.data.to_vec())
}

/// The record starting at `pos`, if it is complete.
fn record_at(buf: &[u8], pos: usize) -> Option<(u8, &[u8])> {
    let prefix = buf.get(pos..pos.checked_add(RECORD_PREFIX)?)?;
    let len = usize::try_from(u64::from_le_bytes(prefix[1..9].try_into().ok()?)).ok()?;
    let start = pos + RECORD_PREFIX;
    let body = buf.get(start..start.checked_add(len)?)?;
    Some((prefix[0], body))
}

fn parse_message(body: &[u8], location: MessageLocation) -> Option<RecordedMessage<'_>> {
    if body.len() < 22 {
        return None;
    }
    Some(RecordedMessage {
        channel_id: u16::from_le_bytes(body[0..2].try_into().ok()?),
        sequence: u32::from_le_bytes(body[2..6].try_into().ok()?),
        log_time: u64::from_le_bytes(body[6..14].try_into().ok()?),
        publish_time: u64::from_le_bytes(body[14..22].try_into().ok()?),
        data: &body[22..],
        location,
    })
}

/// A chunk record's header fields, parsed by hand so a chunk cut short by
/// truncation can still be read.
struct ChunkHeader<'a> {
    uncompressed_size: u64,
    uncompressed_crc: u32,
    compression: &'a str,
    /// The compressed records, possibly shorter than declared when truncated.
    data: &'a [u8],
    declared_len: u64,
}

fn chunk_header(body: &[u8]) -> Option<ChunkHeader<'_>> {
    let u64_at = |p: usize| Some(u64::from_le_bytes(body.get(p..p + 8)?.try_into().ok()?));
    let u32_at = |p: usize| Some(u32::from_le_bytes(body.get(p..p + 4)?.try_into().ok()?));
    // message_start_time u64, message_end_time u64, uncompressed_size u64,
    // uncompressed_crc u32, compression string, compressed_size u64, records.
    let uncompressed_size = u64_at(16)?;
    let uncompressed_crc = u32_at(24)?;
    let name_len = u32_at(28)? as usize;
    let compression = std::str::from_utf8(body.get(32..32 + name_len)?).ok()?;
    let declared_len = u64_at(32 + name_len)?;
    let start = 40 + name_len;
    let end = start.saturating_add(usize::try_from(declared_len).ok()?);
    let data = body.get(start..end.min(body.len()))?;
    Some(ChunkHeader {
        uncompressed_size,
        uncompressed_crc,
        compression,
        data,
        declared_len,
    })
}

/// Where a checked chunk's records are.
enum Records {
    /// Uncompressed: this range of the chunk body.
    InPlace(std::ops::Range<usize>),
    /// Decompressed into the caller's buffer.
    InBuffer,
}

/// What to reserve for a chunk whose header claims `expected` bytes from
/// `compressed`: the claim, unless it is beyond what real chunks reach
/// (then the buffer grows with what the data really decompresses to).
fn claimed_reserve(expected: usize, compressed: usize) -> usize {
    expected.min(compressed.saturating_mul(64).max(1 << 20))
}

/// Decompress and check a complete chunk: its size and, when recorded, its CRC.
fn open_chunk(body: &[u8], out: &mut Vec<u8>) -> Result<Records, String> {
    let header = chunk_header(body).ok_or("malformed chunk header")?;
    if (header.data.len() as u64) < header.declared_len {
        return Err("chunk records run past the chunk".into());
    }
    let expected = usize::try_from(header.uncompressed_size).map_err(|_| "chunk too large")?;
    let (records, located) = match header.compression {
        "" => {
            let start = header.data.as_ptr() as usize - body.as_ptr() as usize;
            (
                header.data,
                Records::InPlace(start..start + header.data.len()),
            )
        }
        "zstd" => {
            out.clear();
            let reserve = claimed_reserve(expected, header.data.len());
            out.reserve(reserve);
            if expected <= reserve {
                // The Vec's spare capacity is the destination (no zero-filling).
                zstd::bulk::Decompressor::new()
                    .and_then(|mut d| d.decompress_to_buffer(header.data, out))
            } else {
                zstd::stream::read::Decoder::new(header.data)
                    .and_then(|d| d.take((expected as u64).saturating_add(1)).read_to_end(out))
            }
            .map_err(|e| format!("zstd decompression failed: {e}"))?;
            (out.as_slice(), Records::InBuffer)
        }
        "lz4" => {
            out.clear();
            out.reserve(claimed_reserve(expected, header.data.len()));
            lz4::Decoder::new(header.data)
                .and_then(|d| d.take((expected as u64).saturating_add(1)).read_to_end(out))
                .map_err(|e| format!("lz4 decompression failed: {e}"))?;
            (out.as_slice(), Records::InBuffer)
        }
        other => return Err(format!("unsupported chunk compression {other:?}")),
    };
    if records.len() != expected {
        return Err(format!(
            "decompressed to {} bytes, header says {expected}",
            records.len()
        ));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(records);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "CRC mismatch (stored {:#010x}, computed {crc:#010x})",
                header.uncompressed_crc
            ));
        }
    }
    Ok(located)
}

/// Emit the schemas, channels and messages of a chunk's records. The records
/// are framed first, so a chunk with a broken record emits nothing.
fn walk_records(
    records: &[u8],
    chunk_offset: u64,
    links: &mut ChannelLinks,
    visit: &mut impl FnMut(ScanEvent<'_>),
) -> Result<(), String> {
    let framed = frame_records(records);
    if framed.end != records.len() {
        return Err(format!(
            "record at chunk offset {} is cut short",
            framed.end
        ));
    }
    emit_records(&framed.records, records, chunk_offset, links, visit);
    Ok(())
}

struct Framed {
    /// (opcode, record offset, body range)
    records: Vec<(u8, usize, std::ops::Range<usize>)>,
    /// Offset after the last complete record.
    end: usize,
}

fn frame_records(records: &[u8]) -> Framed {
    let mut framed = Framed {
        records: Vec::new(),
        end: 0,
    };
    let mut pos = 0;
    while let Some((opcode, body)) = record_at(records, pos) {
        let start = pos + RECORD_PREFIX;
        framed
            .records
            .push((opcode, pos, start..start + body.len()));
        pos = start + body.len();
    }
    framed.end = pos;
    framed
}

/// Returns the number of messages emitted.
fn emit_records(
    framed: &[(u8, usize, std::ops::Range<usize>)],
    records: &[u8],
    chunk_offset: u64,
    links: &mut ChannelLinks,
    visit: &mut impl FnMut(ScanEvent<'_>),
) -> u64 {
    let mut messages = 0;
    for (opcode, offset, range) in framed {
        let body = &records[range.clone()];
        match *opcode {
            op::SCHEMA | op::CHANNEL => {
                // A bad schema or channel record leaves its messages unlinked;
                // they are then counted under an unknown channel.
                let _ = links.add(*opcode, body, visit);
            }
            op::MESSAGE => {
                let location = MessageLocation {
                    chunk_offset: Some(chunk_offset),
                    record_offset: *offset as u64,
                };
                if let Some(message) = parse_message(body, location) {
                    visit(ScanEvent::Message(message));
                    messages += 1;
                }
            }
            _ => {}
        }
    }
    messages
}

/// Recover the complete records at the front of a chunk that the end of the
/// file cut off, noting how many in the report.
fn salvage_partial_chunk(
    chunk_offset: u64,
    body: &[u8],
    links: &mut ChannelLinks,
    visit: &mut impl FnMut(ScanEvent<'_>),
    report: &mut ScanReport,
) {
    let Some(header) = chunk_header(body) else {
        return;
    };
    let mut out = Vec::new();
    let records: &[u8] = match header.compression {
        "" => header.data,
        // Streaming decoders give up at the cut; what came before is kept.
        "zstd" => match zstd::stream::read::Decoder::with_buffer(header.data) {
            Ok(mut d) => {
                let _ = read_until_error(&mut d, &mut out);
                &out
            }
            Err(_) => return,
        },
        "lz4" => match lz4::Decoder::new(header.data) {
            Ok(mut d) => {
                let _ = read_until_error(&mut d, &mut out);
                &out
            }
            Err(_) => return,
        },
        _ => return,
    };
    let framed = frame_records(records);
    let salvaged = emit_records(&framed.records, records, chunk_offset, links, visit);
    if salvaged > 0 {
        report.problems.push(format!(
            "chunk at byte {chunk_offset} is cut off by the end of the file; {salvaged} complete messages recovered from it"
        ));
    }
}

fn read_until_error(reader: &mut impl std::io::Read, out: &mut Vec<u8>) -> std::io::Result<()> {
    let mut block = [0u8; 64 * 1024];
    loop {
        let n = reader.read(&mut block)?;
        if n == 0 {
            return Ok(());
        }
        out.extend_from_slice(&block[..n]);
    }
}

/// Schemas and channels seen so far, linked by id.
#[derive(Default)]
struct ChannelLinks {
    /// Name, encoding and text of each schema.
    schemas: HashMap<u16, (String, String, String)>,
    channels: HashMap<u16, Channel>,
}

impl ChannelLinks {
    fn add(
        &mut self,
        opcode: u8,
        body: &[u8],
        visit: &mut impl FnMut(ScanEvent<'_>),
    ) -> Result<(), String> {
        match mcap::parse_record(opcode, body).map_err(|e| e.to_string())? {
            mcap::records::Record::Schema { header, data } => {
                let text = String::from_utf8_lossy(&data).into_owned();
                self.schemas
                    .insert(header.id, (header.name, header.encoding, text));
            }
            mcap::records::Record::Channel(c) => {
                if self.channels.contains_key(&c.id) {
                    return Ok(()); // chunks repeat channel records
                }
                let (schema, schema_encoding, definition) =
                    self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                let channel = Channel {
                    id: c.id,
                    topic: c.topic,
                    schema,
                    schema_encoding,
                    message_encoding: c.message_encoding,
                    definition,
                };
                visit(ScanEvent::Channel(&channel));
                self.channels.insert(channel.id, channel);
            }
            _ => {}
        }
        Ok(())
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// The most file-backed memory this process held resident since it was
    /// made, above what it held then.
    struct Resident {
        base: u64,
        peak: u64,
    }

    impl Resident {
        fn now() -> u64 {
            let status = std::fs::read_to_string("/proc/self/status").unwrap();
            let line = status.lines().find(|l| l.starts_with("RssFile:")).unwrap();
            let kb: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
            kb * 1024
        }

        fn start() -> Self {
            let base = Self::now();
            Self { base, peak: base }
        }

        fn sample(&mut self) {
            self.peak = self.peak.max(Self::now());
        }

        /// Says how much of `size_mib` the pass `what` held, which must be
        /// under `bound_mib`.
        fn check(&self, what: &str, size_mib: u64, bound_mib: u64) {
            let held = (self.peak - self.base) >> 20;
            eprintln!("{what} {size_mib} MiB held at most {held} MiB of it");
            assert!(held < bound_mib, "{what} held {held} MiB");
        }
    }

    /// Message `i`'s payload: `MESSAGE` bytes of its own.
    fn payload(i: usize) -> Vec<u8> {
        (0..MESSAGE).map(|k| (k / 4096 + i) as u8).collect()
    }

    const MESSAGE: usize = 4 << 20;
    const MESSAGES: usize = 64;

    /// Both passes read every byte (the scan checks each chunk's CRC), so
    /// without handing pages back each would hold the whole file.
    #[test]
    fn a_long_recording_read_front_to_back_stays_within_bounded_resident_memory() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("long.mcap");
        let file = std::io::BufWriter::new(File::create(&path).unwrap());
        let mut out = mcap::WriteOptions::new()
            .compression(None)
            .chunk_size(Some(MESSAGE as u64))
            .create(file)
            .unwrap();
        let channel = out
            .add_channel(0, "/blob", "application/octet-stream", &Default::default())
            .unwrap();
        for i in 0..MESSAGES {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time: i as u64,
                publish_time: i as u64,
            };
            out.write_to_known_channel(&header, &payload(i)).unwrap();
        }
        out.finish().unwrap();
        drop(out);
        let size_mib = ((MESSAGE * MESSAGES) >> 20) as u64;
        let bound_mib = ((RELEASE_LAG + RELEASE_STEP + 2 * MESSAGE) >> 20) as u64;
        assert!(bound_mib + 64 < size_mib);

        let recording = Recording::open(&path).unwrap();
        let mut resident = Resident::start();
        let mut locations = Vec::new();
        let report = recording.scan(|event| {
            if let ScanEvent::Message(m) = event {
                locations.push(m.location);
            }
            resident.sample();
        });
        assert_eq!(report.corrupt_chunks, 0);
        assert_eq!(locations.len(), MESSAGES);
        resident.check("scanning", size_mib, bound_mib);

        // A second pass, reading every message: the same bound, the same bytes.
        let mut resident = Resident::start();
        for (i, location) in locations.iter().enumerate() {
            assert!(
                recording.read_message(*location).unwrap() == payload(i),
                "message {i}"
            );
            resident.sample();
        }
        resident.check("reading", size_mib, bound_mib);
    }
}
