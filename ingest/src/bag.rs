//! Reading a ROS 1 bag (format 2.0), tolerant of the same damage as MCAP
//! ([`crate::recording`]): a recording cut off mid-chunk, a bag whose
//! recorder died before writing its index, chunks whose bytes are corrupt.
//!
//! A bag is a run of records, each a header of `name=value` fields and a
//! data block. Messages and their connections live in chunks (uncompressed,
//! bz2 or lz4); after the chunks an index section lists every connection
//! and where each chunk is. When that index is whole the chunks are read
//! through it; when it is missing (the recorder was killed) or cut off, by
//! a linear scan of the records, salvaging the complete messages of a chunk
//! cut by the end of the file. The `rosbag` crate reads only whole, indexed
//! bags (it panics on the others), so this reader is postflight's own; the
//! `ingest_vs_cat` benchmark measures it against `rosbag`.

use std::collections::HashMap;
use std::io::Read;

use postflight_core::frame::MessageLocation;

use crate::recording::{Channel, RecordedMessage, ScanEvent, ScanReport};
use crate::ros::wire::encoding;

/// The first bytes of every bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// Record opcodes (the `op` header field).
mod op {
    pub const MESSAGE: u8 = 0x02;
    pub const BAG_HEADER: u8 = 0x03;
    pub const CHUNK: u8 = 0x05;
    pub const CHUNK_INFO: u8 = 0x06;
    pub const CONNECTION: u8 = 0x07;
}

/// The header fields postflight reads, whichever record they belong to.
#[derive(Debug, Default)]
struct Header<'a> {
    op: Option<u8>,
    conn: Option<u32>,
    time: Option<u64>,
    compression: Option<&'a str>,
    size: Option<u32>,
    index_pos: Option<u64>,
    conn_count: Option<u32>,
    chunk_count: Option<u32>,
    chunk_pos: Option<u64>,
    topic: Option<&'a str>,
}

impl<'a> Header<'a> {
    fn parse(mut bytes: &'a [u8]) -> Result<Self, String> {
        let mut h = Header::default();
        while !bytes.is_empty() {
            let len = u32_at(bytes, 0).ok_or("header field cut short")? as usize;
            let field = bytes
                .get(4..4usize.saturating_add(len))
                .ok_or("header field runs past its header")?;
            bytes = &bytes[4 + len..];
            let eq = field
                .iter()
                .position(|&b| b == b'=')
                .ok_or("header field without `=`")?;
            let (name, value) = (&field[..eq], &field[eq + 1..]);
            let text = || std::str::from_utf8(value).map_err(|_| "header text is not UTF-8");
            match name {
                b"op" => h.op = value.first().copied(),
                b"conn" => h.conn = u32_at(value, 0),
                b"time" => h.time = time(value),
                b"compression" => h.compression = Some(text()?),
                b"size" => h.size = u32_at(value, 0),
                b"index_pos" => h.index_pos = u64_at(value, 0),
                b"conn_count" => h.conn_count = u32_at(value, 0),
                b"chunk_count" => h.chunk_count = u32_at(value, 0),
                b"chunk_pos" => h.chunk_pos = u64_at(value, 0),
                b"topic" => h.topic = Some(text()?),
                _ => {}
            }
        }
        Ok(h)
    }
}

/// A connection record's data: the `name=value` fields of its connection
/// header (`topic`, `type`, `md5sum`, `message_definition`, ...).
fn connection_fields(mut data: &[u8]) -> HashMap<String, String> {
    let mut fields = HashMap::new();
    while let Some(len) = u32_at(data, 0) {
        let Some(field) = data.get(4..4usize.saturating_add(len as usize)) else {
            break;
        };
        if let Some(eq) = field.iter().position(|&b| b == b'=') {
            fields.insert(
                String::from_utf8_lossy(&field[..eq]).into_owned(),
                String::from_utf8_lossy(&field[eq + 1..]).into_owned(),
            );
        }
        data = &data[4 + len as usize..];
    }
    fields
}

fn u32_at(buf: &[u8], pos: usize) -> Option<u32> {
    Some(u32::from_le_bytes(buf.get(pos..pos + 4)?.try_into().ok()?))
}

fn u64_at(buf: &[u8], pos: usize) -> Option<u64> {
    Some(u64::from_le_bytes(buf.get(pos..pos + 8)?.try_into().ok()?))
}

/// A bag time (`uint32` seconds, `uint32` nanoseconds) in nanoseconds.
fn time(value: &[u8]) -> Option<u64> {
    let (sec, nsec) = (u32_at(value, 0)?, u32_at(value, 4)?);
    Some(u64::from(sec) * 1_000_000_000 + u64::from(nsec))
}

/// One record of `buf` at `pos`.
struct Record<'a> {
    header: &'a [u8],
    data: &'a [u8],
    /// Where the next record starts.
    end: usize,
}

/// How much of the record at `pos` the buffer holds.
enum Found<'a> {
    Whole(Record<'a>),
    /// Its header is whole, its data cut off by the end of the buffer.
    Cut {
        header: &'a [u8],
        data: &'a [u8],
    },
    /// Not even its header is whole.
    Nothing,
}

fn record_at(buf: &[u8], pos: usize) -> Found<'_> {
    let Some(header_len) = u32_at(buf, pos) else {
        return Found::Nothing;
    };
    let header_start = pos + 4;
    let Some(header) = header_start
        .checked_add(header_len as usize)
        .and_then(|end| buf.get(header_start..end))
    else {
        return Found::Nothing;
    };
    let data_len_at = header_start + header.len();
    let Some(data_len) = u32_at(buf, data_len_at) else {
        return Found::Cut { header, data: &[] };
    };
    let data_start = data_len_at + 4;
    let data_end = data_start.saturating_add(data_len as usize);
    match buf.get(data_start..data_end) {
        Some(data) => Found::Whole(Record {
            header,
            data,
            end: data_end,
        }),
        None => Found::Cut {
            header,
            data: &buf[data_start.min(buf.len())..],
        },
    }
}

/// A chunk's records: in place when uncompressed, else decompressed into
/// the caller's buffer. `salvage` keeps what a cut stream still gives.
fn open_chunk<'a>(
    header: &Header<'_>,
    data: &'a [u8],
    out: &'a mut Vec<u8>,
    salvage: bool,
) -> Result<&'a [u8], String> {
    let compression = header.compression.unwrap_or("none");
    let size = header.size.ok_or("chunk header has no size")? as usize;
    out.clear();
    let result = match compression {
        "none" => return Ok(if salvage { data } else { exact(data, size)? }),
        // The size is the header's claim; reserve no more than the data
        // could expand to at the best ratio either codec reaches.
        "bz2" => {
            out.reserve(size.min(data.len().saturating_mul(64)));
            bzip2::read::BzDecoder::new(data).read_to_end(out)
        }
        "lz4" => {
            out.reserve(size.min(data.len().saturating_mul(256)));
            lz4::Decoder::new(data).and_then(|mut d| d.read_to_end(out))
        }
        other => return Err(format!("unsupported chunk compression {other:?}")),
    };
    if salvage {
        return Ok(out);
    }
    result.map_err(|e| format!("{compression} decompression failed: {e}"))?;
    exact(out, size)
}

fn exact(records: &[u8], size: usize) -> Result<&[u8], String> {
    if records.len() == size {
        Ok(records)
    } else {
        Err(format!(
            "chunk holds {} bytes of records, its header says {size}",
            records.len()
        ))
    }
}

/// The connections met so far, by connection id.
#[derive(Default)]
struct Connections {
    known: HashMap<u32, u16>,
}

impl Connections {
    /// A connection record: announce its channel the first time.
    fn add(
        &mut self,
        header: &Header<'_>,
        data: &[u8],
        visit: &mut impl FnMut(ScanEvent<'_>),
    ) -> Result<(), String> {
        let conn = header.conn.ok_or("connection record without conn")?;
        if self.known.contains_key(&conn) {
            return Ok(()); // each chunk repeats its connections, so does the index
        }
        let id = u16::try_from(conn).map_err(|_| format!("connection id {conn} is too large"))?;
        let mut fields = connection_fields(data);
        let topic = header
            .topic
            .map(str::to_string)
            .or_else(|| fields.remove("topic"))
            .ok_or("connection record without a topic")?;
        let channel = Channel {
            id,
            topic,
            schema: fields.remove("type").unwrap_or_default(),
            schema_encoding: "ros1msg".to_string(),
            message_encoding: encoding::ROS1.to_string(),
            definition: fields.remove("message_definition").unwrap_or_default(),
        };
        visit(ScanEvent::Channel(&channel));
        self.known.insert(conn, id);
        Ok(())
    }
}

/// Walk one chunk's records, emitting connections and messages; the count
/// of messages, or why the records stop making sense part-way.
fn walk_chunk(
    records: &[u8],
    chunk_offset: u64,
    connections: &mut Connections,
    visit: &mut impl FnMut(ScanEvent<'_>),
) -> (u64, Result<(), String>) {
    let mut pos = 0;
    let mut messages = 0;
    while pos < records.len() {
        let Found::Whole(record) = record_at(records, pos) else {
            return (
                messages,
                Err(format!("record at chunk offset {pos} is cut short")),
            );
        };
        let header = match Header::parse(record.header) {
            Ok(h) => h,
            Err(e) => return (messages, Err(format!("record at chunk offset {pos}: {e}"))),
        };
        match header.op {
            Some(op::CONNECTION) => {
                if let Err(e) = connections.add(&header, record.data, visit) {
                    return (messages, Err(format!("record at chunk offset {pos}: {e}")));
                }
            }
            Some(op::MESSAGE) => {
                let (Some(conn), Some(time)) = (header.conn, header.time) else {
                    return (
                        messages,
                        Err(format!("message at chunk offset {pos} lacks conn or time")),
                    );
                };
                let Some(&channel_id) = connections.known.get(&conn) else {
                    return (
                        messages,
                        Err(format!(
                            "message at chunk offset {pos} names connection {conn}, which no record defines"
                        )),
                    );
                };
                visit(ScanEvent::Message(RecordedMessage {
                    channel_id,
                    sequence: 0,
                    log_time: time,
                    publish_time: time,
                    data: record.data,
                    location: MessageLocation {
                        chunk_offset: Some(chunk_offset),
                        record_offset: pos as u64,
                    },
                }));
                messages += 1;
            }
            _ => {}
        }
        pos = record.end;
    }
    (messages, Ok(()))
}

/// Where the chunks are, from the index section.
struct Index<'a> {
    /// Connection records: header and data.
    connections: Vec<(Header<'a>, &'a [u8])>,
    /// File offsets of the chunk records, in file order.
    chunks: Vec<u64>,
}

/// Why the index cannot be used (then the bag is read record by record).
enum NoIndex {
    /// The bag header says it has none: its recorder did not close it.
    Missing,
    /// It ends before it lists every connection and chunk the bag header
    /// counts: the file was cut short.
    Cut,
    /// Its records do not make sense.
    Damaged,
}

fn read_index<'a>(
    buf: &'a [u8],
    bag: &Header<'_>,
    first_record: usize,
) -> Result<Index<'a>, NoIndex> {
    let index_pos = bag.index_pos.unwrap_or(0);
    if index_pos == 0 {
        return Err(NoIndex::Missing);
    }
    let mut pos = usize::try_from(index_pos).map_err(|_| NoIndex::Cut)?;
    if pos >= buf.len() {
        return Err(NoIndex::Cut);
    }
    if pos < first_record {
        return Err(NoIndex::Damaged);
    }
    let mut index = Index {
        connections: Vec::new(),
        chunks: Vec::new(),
    };
    while pos < buf.len() {
        let Found::Whole(record) = record_at(buf, pos) else {
            return Err(NoIndex::Cut);
        };
        let header = Header::parse(record.header).map_err(|_| NoIndex::Damaged)?;
        match header.op {
            Some(op::CONNECTION) => index.connections.push((header, record.data)),
            Some(op::CHUNK_INFO) => {
                let at = header.chunk_pos.ok_or(NoIndex::Damaged)?;
                if at < first_record as u64 || at >= index_pos {
                    return Err(NoIndex::Damaged);
                }
                index.chunks.push(at);
            }
            _ => {}
        }
        pos = record.end;
    }
    let counted = |n: usize, claimed: Option<u32>| claimed.is_none_or(|c| n as u64 >= u64::from(c));
    if !counted(index.connections.len(), bag.conn_count)
        || !counted(index.chunks.len(), bag.chunk_count)
    {
        return Err(NoIndex::Cut);
    }
    index.chunks.sort_unstable();
    Ok(index)
}

/// Walk a bag once (through its index when it has a whole one, else
/// record by record), calling `visit` for every connection and message.
pub fn scan(buf: &[u8], mut visit: impl FnMut(ScanEvent<'_>)) -> ScanReport {
    let mut report = ScanReport::default();
    let mut connections = Connections::default();
    let first = MAGIC.len();
    let bag_header = match record_at(buf, first) {
        Found::Whole(r) => Header::parse(r.header).ok().map(|h| (h, r.end)),
        _ => None,
    };
    let Some((bag_header, chunks_start)) = bag_header.filter(|(h, _)| h.op == Some(op::BAG_HEADER))
    else {
        report.truncated = true;
        report.truncated_at = Some(first as u64);
        report
            .problems
            .push("the bag header record is missing or cut off".to_string());
        return report;
    };
    match read_index(buf, &bag_header, chunks_start) {
        Ok(index) => {
            for (header, data) in &index.connections {
                if let Err(e) = connections.add(header, data, &mut visit) {
                    report
                        .problems
                        .push(format!("index connection: {e}; skipped"));
                }
            }
            let mut out = Vec::new();
            for &at in &index.chunks {
                progress(&mut visit, at);
                chunk(
                    buf,
                    at as usize,
                    &mut out,
                    &mut connections,
                    &mut visit,
                    &mut report,
                );
            }
        }
        Err(no_index) => {
            linear(buf, chunks_start, &mut connections, &mut visit, &mut report);
            match no_index {
                NoIndex::Missing => report.problems.push(
                    "the bag has no index (its recorder did not close it); read record by record"
                        .to_string(),
                ),
                // The chunks before the cut may be whole; the recording is not.
                NoIndex::Cut => {
                    report.truncated = true;
                    report.truncated_at.get_or_insert(buf.len() as u64);
                }
                NoIndex::Damaged => report
                    .problems
                    .push("the bag's index is damaged; read record by record".to_string()),
            }
        }
    }
    visit(ScanEvent::Progress {
        bytes: buf.len() as u64,
    });
    report
}

fn progress(visit: &mut impl FnMut(ScanEvent<'_>), at: u64) {
    visit(ScanEvent::Progress { bytes: at });
}

/// Read the records from `pos` to the end of the file, in order.
fn linear(
    buf: &[u8],
    mut pos: usize,
    connections: &mut Connections,
    visit: &mut impl FnMut(ScanEvent<'_>),
    report: &mut ScanReport,
) {
    let mut out = Vec::new();
    let mut last_progress = 0;
    while pos < buf.len() {
        if pos - last_progress >= 4 << 20 {
            progress(visit, pos as u64);
            last_progress = pos;
        }
        let end = match record_at(buf, pos) {
            Found::Whole(record) => {
                let header = Header::parse(record.header);
                match header.as_ref().ok().and_then(|h| h.op) {
                    Some(op::CHUNK) => chunk(buf, pos, &mut out, connections, visit, report),
                    Some(op::CONNECTION) => {
                        let header = header.as_ref().expect("parsed above");
                        if let Err(e) = connections.add(header, record.data, visit) {
                            report
                                .problems
                                .push(format!("record at byte {pos}: {e}; skipped"));
                        }
                    }
                    _ => {}
                }
                record.end
            }
            Found::Cut { .. } | Found::Nothing => {
                chunk(buf, pos, &mut out, connections, visit, report);
                report.truncated = true;
                report.truncated_at = Some(pos as u64);
                return;
            }
        };
        pos = end;
    }
}

/// Read the chunk record at `pos`: whole, or cut by the end of the file
/// (then its complete messages are salvaged). Other records are ignored.
fn chunk(
    buf: &[u8],
    pos: usize,
    out: &mut Vec<u8>,
    connections: &mut Connections,
    visit: &mut impl FnMut(ScanEvent<'_>),
    report: &mut ScanReport,
) {
    let corrupt = |report: &mut ScanReport, e: String| {
        report.corrupt_chunks += 1;
        report
            .problems
            .push(format!("chunk at byte {pos}: {e}; skipped"));
    };
    let ChunkRecord { header, data, cut } = match chunk_at(buf, pos) {
        Ok(Some(chunk)) => chunk,
        Ok(None) => return,
        Err(e) => return corrupt(report, e),
    };
    let records = match open_chunk(&header, data, out, cut) {
        Ok(records) => records,
        Err(e) => return corrupt(report, e),
    };
    let (messages, walked) = walk_chunk(records, pos as u64, connections, visit);
    match (cut, walked) {
        (false, Ok(())) => {}
        (false, Err(e)) => {
            report.corrupt_chunks += 1;
            report.problems.push(format!(
                "chunk at byte {pos}: {e}; the rest of the chunk skipped ({messages} messages read)"
            ));
        }
        (true, _) if messages > 0 => report.problems.push(format!(
            "chunk at byte {pos} is cut off by the end of the file; {messages} complete messages recovered from it"
        )),
        (true, _) => {}
    }
}

/// The data of the message at `location`, reading (and caching) its chunk.
pub(crate) fn read_message(
    buf: &[u8],
    location: MessageLocation,
    cache: &mut Option<(u64, Vec<u8>)>,
) -> Result<Vec<u8>, String> {
    let chunk_offset = location
        .chunk_offset
        .ok_or("bag messages are always in chunks")?;
    let fetch = |records: &[u8]| match record_at(records, location.record_offset as usize) {
        Found::Whole(record) => match Header::parse(record.header) {
            Ok(h) if h.op == Some(op::MESSAGE) => Ok(record.data.to_vec()),
            _ => Err("not a message record".to_string()),
        },
        _ => Err("record past the end of its chunk".to_string()),
    };
    if let Some((offset, records)) = cache.as_ref()
        && *offset == chunk_offset
    {
        return fetch(records);
    }
    let pos = usize::try_from(chunk_offset).map_err(|_| "chunk offset out of range")?;
    let chunk = chunk_at(buf, pos)?.ok_or("not a chunk record")?;
    let mut out = Vec::new();
    let records = open_chunk(&chunk.header, chunk.data, &mut out, chunk.cut)?;
    let result = fetch(records);
    // Uncompressed chunks are read in place; nothing to cache.
    if !out.is_empty() {
        *cache = Some((chunk_offset, out));
    }
    result
}

/// A chunk record: its header, and its data, `cut` short by the end of
/// the file or whole.
struct ChunkRecord<'a> {
    header: Header<'a>,
    data: &'a [u8],
    cut: bool,
}

/// The chunk record at `pos`; `None` when another record (or nothing) is there.
fn chunk_at(buf: &[u8], pos: usize) -> Result<Option<ChunkRecord<'_>>, String> {
    let (header, data, cut) = match record_at(buf, pos) {
        Found::Whole(r) => (r.header, r.data, false),
        Found::Cut { header, data } => (header, data, true),
        Found::Nothing => return Ok(None),
    };
    let header = Header::parse(header)?;
    Ok((header.op == Some(op::CHUNK)).then_some(ChunkRecord { header, data, cut }))
}
