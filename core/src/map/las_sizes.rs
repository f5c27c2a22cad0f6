//! A LAS or LAZ file's sizes checked against the file's own size before
//! the `las` and `laz` crates read it. They trust three sizes they read
//! and allocate them before reading the bytes: each extended VLR's length
//! (LAS 1.4), the LAZ chunk table's number of chunks (an entry reserved for
//! each) and, in the layered compression of point formats 6 to 10, each
//! chunk's layer sizes. A corrupt size would take gigabytes for a file of
//! kilobytes (found by fuzzing), so each is checked here to fit in the
//! file. Anything else wrong is left to the readers, which report it
//! without allocating what the file claims.

use std::io::{Cursor, Read, Seek, SeekFrom};

use laz::laszip::{ChunkTable, LazItemType, LazVlr};

/// Refuses a LAS 1.4 file whose extended VLRs claim more bytes than it
/// holds; reads only their headers, so a file's header can be checked
/// without reading its points.
pub(super) fn check_evlrs<R: Read + Seek>(mut file: R) -> Result<(), String> {
    let unreadable = |e: std::io::Error| format!("it cannot be read ({e})");
    let len = file.seek(SeekFrom::End(0)).map_err(unreadable)?;
    let mut head = [0u8; 247];
    file.seek(SeekFrom::Start(0)).map_err(unreadable)?;
    // Too short, or before LAS 1.4 (bytes 24 and 25): no extended VLRs.
    if file.read_exact(&mut head).is_err() || head[24] != 1 || head[25] < 4 {
        return Ok(());
    }
    let mut at = u64::from_le_bytes(head[235..243].try_into().expect("8 bytes"));
    let count = le_u32(&head[243..247]);
    for n in 1..=count {
        // Each is at least its 60-byte header, so a lying count ends at
        // the file's end.
        let mut evlr = [0u8; 60];
        if file.seek(SeekFrom::Start(at)).is_err() || file.read_exact(&mut evlr).is_err() {
            return Ok(());
        }
        let length = u64::from_le_bytes(evlr[20..28].try_into().expect("8 bytes"));
        match (at + 60).checked_add(length).filter(|&end| end <= len) {
            Some(end) => at = end,
            None => {
                return Err(format!(
                    "its extended VLR {n} claims {length} bytes, more than the file's {len} bytes hold; the file is truncated or corrupt"
                ));
            }
        }
    }
    Ok(())
}

/// Refuses a LAZ file whose chunk table or chunks claim more bytes than
/// it holds.
pub(super) fn check_laz(bytes: &[u8], header: &las::Header) -> Result<(), String> {
    let Ok(vlr) = header.laz_vlr() else {
        return Ok(());
    };
    let Some(data_start) = bytes.get(96..100).map(|b| le_u32(b) as usize) else {
        return Ok(());
    };
    let point_bytes = vlr.items_size().max(1) as usize;
    let table = chunk_table(bytes, data_start, &vlr, point_bytes)?;
    let Some(layers) = layers_per_chunk(&vlr) else {
        return Ok(());
    };
    walk_layers(
        bytes,
        data_start,
        &vlr,
        table.as_ref(),
        layers,
        header.number_of_points(),
    )
}

/// The chunk table, once its number of chunks is known to fit: every chunk
/// holds at least its first point uncompressed. `None` where there is no
/// table to read (the decoder then goes without it, or says it is missing).
fn chunk_table(
    bytes: &[u8],
    data_start: usize,
    vlr: &LazVlr,
    point_bytes: usize,
) -> Result<Option<ChunkTable>, String> {
    let Some(table_at) = chunk_table_offset(bytes, data_start) else {
        return Ok(None);
    };
    let Some(count) = bytes.get(table_at + 4..table_at + 8).map(le_u32) else {
        return Ok(None);
    };
    let room = bytes.len() / point_bytes;
    if count as usize > room {
        return Err(format!(
            "its LAZ chunk table claims {count} chunks, more than the file's {} bytes hold ({room} at most); the file is truncated or corrupt",
            bytes.len()
        ));
    }
    let mut source = Cursor::new(bytes);
    let table = source
        .seek(SeekFrom::Start(data_start as u64))
        .ok()
        .and_then(|_| ChunkTable::read_from(&mut source, vlr).ok());
    Ok(table)
}

/// Where the chunk table is, as the decoder finds it: the offset at the
/// start of the point data, or, where a writer could not go back to write
/// it, in the file's last eight bytes.
fn chunk_table_offset(bytes: &[u8], data_start: usize) -> Option<usize> {
    let after_start = |at: usize| {
        let offset = i64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?);
        usize::try_from(offset).ok().filter(|&o| o > data_start)
    };
    after_start(data_start).or_else(|| after_start(bytes.len().checked_sub(8)?))
}

/// Layer sizes each chunk states, where the compression is layered (item
/// versions 3 and 4, as the decoder chooses); `None` for the point-wise
/// compression of formats 0 to 5, which allocates nothing from the file.
fn layers_per_chunk(vlr: &LazVlr) -> Option<usize> {
    let items = vlr.items();
    if !matches!(items.first()?.version(), 3 | 4) {
        return None;
    }
    let layers = items.iter().map(|item| match item.item_type() {
        LazItemType::Point14 => 9,
        LazItemType::RGB14 | LazItemType::WavePacket14 => 1,
        LazItemType::RGBNIR14 => 2,
        LazItemType::Byte14(count) => usize::from(count),
        _ => 0,
    });
    Some(layers.sum())
}

/// Walks the chunks as the decoder reads them (its first point, its point
/// count, a size per layer, then the layers) for as many points as the
/// header gives, and refuses the first chunk whose layers the file cannot
/// hold. A chunk whose sizes run past the file's end stops the walk: the
/// decoder fails there too, on reading them, before allocating.
fn walk_layers(
    bytes: &[u8],
    data_start: usize,
    vlr: &LazVlr,
    table: Option<&ChunkTable>,
    layers: usize,
    points: u64,
) -> Result<(), String> {
    let first_point = vlr.items_size() as usize;
    let mut at = data_start + 8;
    let mut left = points;
    let mut chunk = 0;
    while left > 0 {
        let sizes_at = at + first_point + 4;
        let Some(sizes) = bytes.get(sizes_at..sizes_at + 4 * layers) else {
            return Ok(());
        };
        let claimed: u64 = sizes.chunks_exact(4).map(|s| u64::from(le_u32(s))).sum();
        let end = (sizes_at + sizes.len()) as u64 + claimed;
        if end > bytes.len() as u64 {
            return Err(format!(
                "its LAZ chunk {} claims {claimed} bytes of compressed layers, more than the file's {} bytes hold; the file is truncated or corrupt",
                chunk + 1,
                bytes.len()
            ));
        }
        at = end as usize;
        // A chunk of no points (a fixed size of 0, a table's 0, variable
        // sizes without a table) holds the rest, as the decoder reads it;
        // past the table's end the decoder gives up.
        let in_chunk = match (vlr.uses_variable_size_chunks(), table) {
            (false, _) => u64::from(vlr.chunk_size()),
            (true, Some(table)) => match table.as_ref().get(chunk) {
                Some(entry) => entry.point_count,
                None => return Ok(()),
            },
            (true, None) => 0,
        };
        left = if in_chunk == 0 {
            0
        } else {
            left.saturating_sub(in_chunk)
        };
        chunk += 1;
    }
    Ok(())
}

fn le_u32(bytes: &[u8]) -> u32 {
    u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])
}
