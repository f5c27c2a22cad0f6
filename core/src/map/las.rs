//! LAS and LAZ point clouds (ASPRS LAS 1.0 to 1.4, LAZ through the `laz`
//! crate) with the coordinate reference system their VLRs give: a WKT CRS,
//! or GeoTIFF keys (the projected CRS, else the geographic one).

use std::io::Cursor;

use nalgebra::Point3;

use crate::crs::Crs;

/// Every point of a LAS or LAZ file, in its coordinates, and its CRS.
pub(super) fn parse(bytes: &[u8]) -> Result<(Vec<Point3<f64>>, Crs), String> {
    let mut reader = las::Reader::new(Cursor::new(bytes.to_vec()))
        .map_err(|e| format!("it is not a readable LAS or LAZ file ({e})"))?;
    let crs = crs_of(reader.header())?;
    let points = reader
        .read_all()
        .map_err(|e| format!("its points cannot be read ({e})"))?;
    let points = points
        .x()
        .zip(points.y())
        .zip(points.z())
        .map(|((x, y), z)| Point3::new(x, y, z))
        .collect();
    Ok((points, crs))
}

/// The CRS of the LAS or LAZ file at `path`, from its header alone.
pub(super) fn crs_of_file(path: &std::path::Path) -> Result<Crs, String> {
    let reader = las::Reader::from_path(path)
        .map_err(|e| format!("it is not a readable LAS or LAZ file ({e})"))?;
    crs_of(reader.header())
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
