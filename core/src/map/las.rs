//! LAS and LAZ point clouds (ASPRS LAS 1.0 to 1.4, LAZ through the `laz`
//! crate) with the coordinate reference system their VLRs give: a WKT CRS,
//! or GeoTIFF keys (the projected CRS, else the geographic one).

use std::io::Cursor;

use nalgebra::Point3;

use super::las_sizes;
use crate::crs::Crs;

/// Every point of a LAS or LAZ file, in its coordinates, and its CRS.
pub fn parse(bytes: &[u8]) -> Result<(Vec<Point3<f64>>, Crs), String> {
    guarded(|| parse_unguarded(bytes))
}

/// `read`, with a panic of the `las` or `laz` crate on a corrupt file (their
/// overflow checks and assertions in debug builds, found by fuzzing) made
/// the error it is.
fn guarded<T>(read: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(read)).unwrap_or_else(|_| {
        Err("it is not a readable LAS or LAZ file (corrupt: its reader gave up on it)".into())
    })
}

fn parse_unguarded(bytes: &[u8]) -> Result<(Vec<Point3<f64>>, Crs), String> {
    las_sizes::check_evlrs(Cursor::new(bytes))?;
    let header = las::Header::new(Cursor::new(bytes)).map_err(unreadable)?;
    let crs = crs_of(&header)?;
    las_sizes::check_laz(bytes, &header)?;
    let mut reader = las::Reader::new(Cursor::new(bytes.to_vec())).map_err(unreadable)?;
    let header = reader.header();
    let claimed = header.number_of_points();
    // An uncompressed file's points are all in it: a count it cannot hold
    // is refused before any is read.
    let format = header.point_format();
    let needed = claimed.saturating_mul(u64::from(format.len()));
    if !format.is_compressed && needed > bytes.len() as u64 {
        return Err(format!(
            "its header claims {claimed} points ({needed} bytes), more than the file's {} bytes hold; the file is truncated or corrupt",
            bytes.len()
        ));
    }
    // In batches, so memory follows the points there are, not the count a
    // (compressed) file's header claims.
    let mut points = Vec::new();
    let mut batch = las::PointDataBuilder::new().for_header(header).build();
    loop {
        let read = reader
            .fill_points(BATCH, &mut batch)
            .map_err(|e| format!("its points cannot be read ({e})"))?;
        points.extend(
            batch
                .x()
                .zip(batch.y())
                .zip(batch.z())
                .map(|((x, y), z)| Point3::new(x, y, z)),
        );
        if read < BATCH {
            return Ok((points, crs));
        }
    }
}

/// Points read at a time.
const BATCH: u64 = 1 << 16;

/// The CRS of the LAS or LAZ file at `path`, from its header alone.
pub(super) fn crs_of_file(path: &std::path::Path) -> Result<Crs, String> {
    crate::user_file::check(path).map_err(|e| format!("{e}; check the path"))?;
    let open = || std::fs::File::open(path).map(std::io::BufReader::new);
    let file = open().map_err(|e| format!("it cannot be read ({e})"))?;
    guarded(|| {
        las_sizes::check_evlrs(file)?;
        let file = open().map_err(|e| format!("it cannot be read ({e})"))?;
        crs_of(&las::Header::new(file).map_err(unreadable)?)
    })
}

fn unreadable(e: las::Error) -> String {
    format!("it is not a readable LAS or LAZ file ({e})")
}

/// The file's CRS; an error naming what is missing and how to add it.
fn crs_of(header: &las::Header) -> Result<Crs, String> {
    if let Some(wkt) = header.get_wkt_crs_bytes() {
        let text = String::from_utf8_lossy(wkt);
        return Crs::from_wkt(text.trim_end_matches('\0'));
    }
    let keys = header
        .get_geotiff_crs()
        .map_err(|e| format!("its GeoTIFF CRS keys cannot be read ({e})"))?;
    let code = keys.and_then(|k| {
        let epsg = |v: Option<u16>| v.filter(|c| (1024..32767).contains(c));
        epsg(k.get_projected_crs_geo_key_value()).or(epsg(k.get_geodetic_crs_geo_key_value()))
    });
    code.map(|epsg| Crs { epsg }).ok_or_else(|| {
        "it has no coordinate reference system (no WKT or GeoTIFF keys with an EPSG code), so where its points are on the Earth is unknown; assign it one (pdal translate IN OUT --writers.las.a_srs=EPSG:CODE, or laspy's header.add_crs), or give the map as PLY or PCD in the flight's map frame".to_string()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_the_las_reader_panics_on_is_an_error() {
        // Found by the `las` fuzz target (minimised): a header whose sizes
        // overflow the `las` crate's arithmetic (a panic in debug builds);
        // the LAZ decoder's assertions on corrupt streams go the same way.
        let bytes = include_bytes!("fuzzed/las-header-overflow.laz");
        assert!(parse(bytes).is_err());
    }

    /// A LAS 1.4 file of `n` points with a WKT CRS (EPSG:32633).
    fn las_file(n: usize) -> Vec<u8> {
        las_or_laz_file(n, false)
    }

    /// The same, LAZ-compressed where `compressed`.
    fn las_or_laz_file(n: usize, compressed: bool) -> Vec<u8> {
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = las::point::Format::new(6).unwrap();
        builder.point_format.is_compressed = compressed;
        let mut header = builder.into_header().unwrap();
        let wkt = r#"PROJCS["WGS 84 / UTM zone 33N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],UNIT["metre",1],AUTHORITY["EPSG","32633"]]"#;
        header.set_wkt_crs(wkt.as_bytes().to_vec()).unwrap();
        let mut writer = las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
        for i in 0..n {
            writer
                .write_point(las::Point {
                    x: i as f64,
                    y: 2.0,
                    z: 3.0,
                    gps_time: Some(0.0),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.into_inner().unwrap().into_inner()
    }

    #[test]
    fn points_are_read_and_a_count_the_file_cannot_hold_is_refused() {
        let file = las_file(3);
        let (points, crs) = parse(&file).unwrap();
        assert_eq!(crs.epsg, 32633);
        assert_eq!(points.len(), 3);
        assert_eq!(points[2], Point3::new(2.0, 2.0, 3.0));
        // The point counts (the legacy one, bytes 107-110, and LAS 1.4's,
        // 247-254) claim 4,294,967,295 points: refused before any is read
        // or allocated.
        let mut lying = file.clone();
        lying[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
        lying[247..255].copy_from_slice(&u64::from(u32::MAX).to_le_bytes());
        let err = parse(&lying).unwrap_err();
        assert!(err.contains("claims 4294967295 points"), "{err}");
    }

    fn le_u32(bytes: &[u8], at: usize) -> usize {
        u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize
    }

    #[test]
    fn sizes_a_laz_file_cannot_hold_are_refused_before_they_are_allocated() {
        // Found by the `las` fuzz target: a LAZ 1.4 file of 836 kB whose
        // chunk claimed layers the decoder allocated (3.4 GB) before
        // finding their bytes missing. Here a valid file, then its sizes
        // made to lie one at a time.
        let file = las_or_laz_file(100, true);
        assert_eq!(parse(&file).unwrap().0.len(), 100);
        let data = le_u32(&file, 96);
        // The first chunk: the chunk table's offset (8 bytes), a point of
        // format 6 uncompressed (30 bytes), its point count, then the size
        // of each of its 9 layers.
        let mut layers = file.clone();
        let first_layer = data + 8 + 30 + 4;
        layers[first_layer..first_layer + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = parse(&layers).unwrap_err();
        assert!(err.contains("LAZ chunk 1 claims 42949"), "{err}");
        // The chunk table: its version, then its number of chunks.
        let mut table = file.clone();
        let table_at = u64::from_le_bytes(file[data..data + 8].try_into().unwrap()) as usize;
        table[table_at + 4..table_at + 8].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = parse(&table).unwrap_err();
        assert!(
            err.contains("chunk table claims 4294967295 chunks"),
            "{err}"
        );
    }

    #[test]
    fn an_extended_vlr_longer_than_the_file_is_refused() {
        let mut builder = las::Builder::from((1, 4));
        builder.evlrs.push(las::Vlr {
            user_id: "postflight".into(),
            record_id: 1,
            description: "test".into(),
            data: vec![7; 100],
        });
        let header = builder.into_header().unwrap();
        let writer = las::Writer::new(Cursor::new(Vec::new()), header).unwrap();
        let mut file = writer.into_inner().unwrap().into_inner();
        let start = u64::from_le_bytes(file[235..243].try_into().unwrap()) as usize;
        assert_eq!(le_u32(&file, 243), 1);
        file[start + 20..start + 28].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let err = parse(&file).unwrap_err();
        assert!(
            err.contains("extended VLR 1 claims 1099511627776 bytes"),
            "{err}"
        );
        let path = std::env::temp_dir().join(format!("postflight-evlr-{}.las", std::process::id()));
        std::fs::write(&path, &file).unwrap();
        let err = crs_of_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(err.contains("extended VLR 1 claims"), "{err}");
    }
}
