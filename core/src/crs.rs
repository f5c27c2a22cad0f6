//! Coordinate reference systems of survey data (a LAS file's points in UTM,
//! say), by EPSG code, and their coordinates taken onto the WGS 84 Earth
//! through `proj4rs` (PROJ's projections ported to Rust, with the EPSG
//! definitions of `crs-definitions`). Heights pass through as they are:
//! the map's vertical datum must be the photos' (above the ellipsoid, as
//! RTK drones tag them).

use proj4rs::Proj;

use crate::geo::Geodetic;

/// A coordinate reference system, by its EPSG code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crs {
    pub epsg: u16,
}

impl std::fmt::Display for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EPSG:{}", self.epsg)
    }
}

/// Where survey points are on the Earth: their CRS, ready to convert.
pub struct Projection {
    crs: Crs,
    from: Proj,
    to: Proj,
}

impl Crs {
    /// The CRS a WKT text (WKT 1 or 2) names: its EPSG identifier, the
    /// horizontal one of a compound CRS.
    pub fn from_wkt(text: &str) -> Result<Self, String> {
        let node = wkt::parse(text).ok_or_else(|| "its WKT cannot be read".to_string())?;
        let horizontal = match node.keyword.to_ascii_uppercase().as_str() {
            "COMPOUNDCRS" | "COMPD_CS" => node.children.first().unwrap_or(&node),
            _ => &node,
        };
        let code = horizontal
            .epsg()
            .ok_or_else(|| format!("its WKT CRS {:?} has no EPSG identifier", horizontal.name()))?;
        let epsg = u16::try_from(code).map_err(|_| {
            format!("its WKT CRS names EPSG:{code}, which is not a CRS postflight knows")
        })?;
        Ok(Self { epsg })
    }

    /// Ready to convert; an error for a code `crs-definitions` does not
    /// know or a CRS `proj4rs` cannot invert.
    pub fn projection(self) -> Result<Projection, String> {
        let from = Proj::from_epsg_code(self.epsg)
            .map_err(|e| format!("{self} is not a CRS postflight knows ({e})"))?;
        let to = Proj::from_proj_string("+proj=longlat +ellps=WGS84 +datum=WGS84 +no_defs")
            .map_err(|e| e.to_string())?;
        Ok(Projection {
            crs: self,
            from,
            to,
        })
    }
}

impl Projection {
    pub fn crs(&self) -> Crs {
        self.crs
    }

    /// A point's coordinates in the CRS (easting, northing and height; or
    /// longitude and latitude in degrees and height) on the Earth.
    pub fn to_geodetic(&self, x: f64, y: f64, z: f64) -> Result<Geodetic, String> {
        let mut point = match self.from.is_latlong() {
            true => (x.to_radians(), y.to_radians(), z),
            false => (x, y, z),
        };
        proj4rs::transform::transform(&self.from, &self.to, &mut point)
            .map_err(|e| format!("({x}, {y}) is outside {} ({e})", self.crs))?;
        Ok(Geodetic {
            latitude_deg: point.1.to_degrees(),
            longitude_deg: point.0.to_degrees(),
            altitude_m: point.2,
        })
    }
}

/// Enough of WKT's bracket syntax to find a CRS's identifier.
mod wkt {
    /// `KEYWORD[...]`: its quoted and bare values, and its nodes.
    #[derive(Debug, Default)]
    pub(super) struct Node {
        pub(super) keyword: String,
        pub(super) values: Vec<String>,
        pub(super) children: Vec<Node>,
    }

    impl Node {
        /// The CRS's own name (its first value).
        pub(super) fn name(&self) -> &str {
            self.values.first().map_or("", String::as_str)
        }

        /// Its own `ID["EPSG", n]` (WKT 2) or `AUTHORITY["EPSG", "n"]` (WKT 1).
        pub(super) fn epsg(&self) -> Option<u32> {
            self.children.iter().find_map(|c| {
                let is_id = matches!(c.keyword.to_ascii_uppercase().as_str(), "ID" | "AUTHORITY");
                let authority = c.values.first()?;
                (is_id && authority.eq_ignore_ascii_case("EPSG"))
                    .then(|| c.values.get(1)?.parse().ok())
                    .flatten()
            })
        }
    }

    type Chars<'a> = std::iter::Peekable<std::str::Chars<'a>>;

    pub(super) fn parse(text: &str) -> Option<Node> {
        let mut chars = text.trim().chars().peekable();
        let keyword = taken_while(&mut chars, |c| c.is_ascii_alphanumeric() || c == '_');
        node(keyword, &mut chars, 0)
    }

    /// How deep nodes may nest: a CRS's WKT nests under ten deep, and a
    /// file's may not take the stack with it.
    const MAX_DEPTH: usize = 64;

    /// The characters from here while `keep` holds.
    fn taken_while(chars: &mut Chars<'_>, keep: impl Fn(char) -> bool) -> String {
        let mut taken = String::new();
        while let Some(c) = chars.peek().copied().filter(|c| keep(*c)) {
            taken.push(c);
            chars.next();
        }
        taken
    }

    /// The node `keyword` opens, `depth` nodes deep: its bracket, its
    /// values and nodes, and its closing bracket.
    fn node(keyword: String, chars: &mut Chars<'_>, depth: usize) -> Option<Node> {
        if depth > MAX_DEPTH {
            return None;
        }
        let mut node = Node {
            keyword,
            ..Node::default()
        };
        if !matches!(chars.next()?, '[' | '(') {
            return None;
        }
        loop {
            taken_while(chars, |c| c.is_whitespace() || c == ',');
            match *chars.peek()? {
                ']' | ')' => {
                    chars.next();
                    return Some(node);
                }
                '"' => {
                    chars.next();
                    let mut value = String::new();
                    loop {
                        match chars.next()? {
                            // A doubled quote is a quote inside the string.
                            '"' if chars.peek() == Some(&'"') => {
                                chars.next();
                                value.push('"');
                            }
                            '"' => break,
                            c => value.push(c),
                        }
                    }
                    node.values.push(value);
                }
                c if c.is_ascii_alphabetic() => {
                    // A keyword with brackets is a node; without, a bare value.
                    let word = taken_while(chars, |c| c.is_ascii_alphanumeric() || c == '_');
                    match chars.peek() {
                        Some('[' | '(') => {
                            node.children.push(self::node(word, chars, depth + 1)?);
                        }
                        _ => node.values.push(word),
                    }
                }
                _ => {
                    let value = taken_while(chars, |c| !matches!(c, ',' | ']' | ')'));
                    node.values.push(value.trim().to_string());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// WGS 84 / UTM zone 32N as pyproj writes it in WKT 2 (shortened).
    const WKT2: &str = r#"PROJCRS["WGS 84 / UTM zone 32N",BASEGEOGCRS["WGS 84",ENSEMBLE["World Geodetic System 1984 ensemble",MEMBER["World Geodetic System 1984 (Transit)"],ELLIPSOID["WGS 84",6378137,298.257223563,LENGTHUNIT["metre",1]],ENSEMBLEACCURACY[2.0]],PRIMEM["Greenwich",0,ANGLEUNIT["degree",0.0174532925199433]],ID["EPSG",4326]],CONVERSION["UTM zone 32N",METHOD["Transverse Mercator",ID["EPSG",9807]],PARAMETER["Latitude of natural origin",0,ANGLEUNIT["degree",0.0174532925199433],ID["EPSG",8801]]],CS[Cartesian,2],AXIS["(E)",east,ORDER[1],LENGTHUNIT["metre",1]],USAGE[SCOPE["Navigation and medium accuracy spatial referencing."],AREA["Between 6°E and 12°E"],BBOX[0,6,84,12]],ID["EPSG",32632]]"#;
    /// The same in WKT 1, as older LAS writers put it.
    const WKT1: &str = r#"PROJCS["WGS 84 / UTM zone 32N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",9],UNIT["metre",1],AXIS["Easting",EAST],AUTHORITY["EPSG","32632"]]"#;

    #[test]
    fn finds_the_crs_of_wkt_1_2_and_compound() {
        assert_eq!(Crs::from_wkt(WKT2).unwrap().epsg, 32632);
        assert_eq!(Crs::from_wkt(WKT1).unwrap().epsg, 32632);
        let compound = format!(
            r#"COMPOUNDCRS["WGS 84 / UTM zone 32N + EGM96 height",{WKT2},VERTCRS["EGM96 height",ID["EPSG",5773]]]"#
        );
        assert_eq!(Crs::from_wkt(&compound).unwrap().epsg, 32632);
        assert!(
            Crs::from_wkt(r#"LOCAL_CS["site grid",UNIT["metre",1]]"#)
                .unwrap_err()
                .contains("site grid")
        );
        // 32,000 nested nodes: refused, not a stack overflow.
        let deep = format!("{}{}", "A[".repeat(32_000), "]".repeat(32_000));
        assert!(Crs::from_wkt(&deep).unwrap_err().contains("cannot be read"));
        assert!(Crs::from_wkt("not wkt").is_err());
        // A code past any EPSG's is named, not taken for no code at all.
        let err = Crs::from_wkt(&WKT1.replace("\"32632\"", "\"99999\"")).unwrap_err();
        assert!(err.contains("EPSG:99999"), "{err}");
    }

    #[test]
    fn utm_to_the_earth_as_published() {
        // PROJ's figures (pyproj 3.7, EPSG:32632 to EPSG:4326).
        let utm = Crs { epsg: 32632 }.projection().unwrap();
        let g = utm.to_geodetic(500_000.0, 5_000_000.0, 120.0).unwrap();
        assert!((g.longitude_deg - 9.0).abs() < 1e-9, "{g:?}");
        assert!((g.latitude_deg - 45.153_477_183_4).abs() < 1e-9, "{g:?}");
        assert_eq!(g.altitude_m, 120.0);
        let geographic = Crs { epsg: 4326 }.projection().unwrap();
        let g = geographic.to_geodetic(8.5, 47.4, 400.0).unwrap();
        assert!((g.longitude_deg - 8.5).abs() < 1e-12 && (g.latitude_deg - 47.4).abs() < 1e-12);
        assert!(Crs { epsg: 1 }.projection().is_err());
    }
}
