//! The XMP packet of a JPEG (its APP1 segment named by Adobe's namespace)
//! and the properties DJI writes in it under `drone-dji:`, as attributes
//! (DJI's cameras) or as elements (exiftool).

use std::collections::BTreeMap;

use quick_xml::events::Event;
use quick_xml::name::{Namespace, ResolveResult};
use quick_xml::reader::NsReader;

/// The namespace of DJI's camera and flight properties.
const DRONE_DJI: &[u8] = b"http://www.dji.com/drone-dji/1.0/";
/// What an APP1 segment holding XMP starts with.
const XMP_SIGNATURE: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";

/// A JPEG's XMP packet, if it has one: the bytes of its first APP1 segment
/// with the XMP signature.
pub(crate) fn packet(jpeg: &[u8]) -> Option<&[u8]> {
    if !jpeg.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut at = 2;
    while at + 4 <= jpeg.len() && jpeg[at] == 0xFF {
        let marker = jpeg[at + 1];
        // Start of scan: the entropy-coded image follows, no more metadata.
        if marker == 0xDA {
            return None;
        }
        let length = usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
        let body = jpeg.get(at + 4..at + 2 + length)?;
        if marker == 0xE1
            && let Some(xmp) = body.strip_prefix(XMP_SIGNATURE)
        {
            return Some(xmp);
        }
        at += 2 + length;
    }
    None
}

/// The `drone-dji:` properties of an XMP packet, by name
/// (`GimbalYawDegree` to `"+12.30"`); empty without any. An error when the
/// packet is not well-formed XML.
pub(crate) fn drone_dji(packet: &[u8]) -> Result<BTreeMap<String, String>, String> {
    let text = std::str::from_utf8(packet).map_err(|e| format!("its XMP is not UTF-8 ({e})"))?;
    let mut reader = NsReader::from_str(text);
    let mut properties = BTreeMap::new();
    // The DJI element whose text is being read.
    let mut open: Option<String> = None;
    let is_dji = |ns: &ResolveResult<'_>| matches!(ns, ResolveResult::Bound(Namespace(n)) if *n == DRONE_DJI);
    loop {
        let (ns, event) = reader
            .read_resolved_event()
            .map_err(|e| format!("its XMP is not well-formed ({e})"))?;
        match event {
            Event::Start(e) | Event::Empty(e) => {
                let element_is_dji = is_dji(&ns);
                let local = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
                for attribute in e.attributes().flatten() {
                    let (ns, name) = reader.resolver().resolve_attribute(attribute.key);
                    if is_dji(&ns)
                        && let Ok(value) = attribute.unescape_value()
                    {
                        let name = String::from_utf8_lossy(name.as_ref()).into_owned();
                        properties.insert(name, value.trim().to_string());
                    }
                }
                open = element_is_dji.then_some(local);
            }
            Event::Text(t) => {
                if let (Some(name), Ok(value)) = (&open, t.decode()) {
                    let value = value.trim();
                    if !value.is_empty() {
                        properties.insert(name.clone(), value.to_string());
                    }
                }
            }
            Event::End(_) => open = None,
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(properties)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As a DJI camera writes it: properties as attributes.
    const AS_DJI: &str = r#"<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
 <rdf:Description rdf:about="DJI Meta Data" xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/"
   drone-dji:AbsoluteAltitude="+116.56" drone-dji:GimbalYawDegree="-79.00"
   drone-dji:DewarpData="2018-03-13;3659.78,3653.17,-7.71,45.90,-0.269,0.115,-0.0000875,-0.000306,-0.0357"/>
</rdf:RDF></x:xmpmeta>"#;

    /// As exiftool writes it: properties as elements.
    const AS_EXIFTOOL: &str = r#"<x:xmpmeta xmlns:x='adobe:ns:meta/'><rdf:RDF xmlns:rdf='http://www.w3.org/1999/02/22-rdf-syntax-ns#'>
 <rdf:Description rdf:about='' xmlns:drone-dji='http://www.dji.com/drone-dji/1.0/'>
  <drone-dji:AbsoluteAltitude>+100.25</drone-dji:AbsoluteAltitude>
  <drone-dji:GimbalPitchDegree>-30.5</drone-dji:GimbalPitchDegree>
 </rdf:Description></rdf:RDF></x:xmpmeta>"#;

    #[test]
    fn reads_properties_written_as_attributes_or_elements() {
        let dji = drone_dji(AS_DJI.as_bytes()).unwrap();
        assert_eq!(dji["AbsoluteAltitude"], "+116.56");
        assert_eq!(dji["GimbalYawDegree"], "-79.00");
        assert!(dji["DewarpData"].starts_with("2018-03-13;3659.78"));
        let exiftool = drone_dji(AS_EXIFTOOL.as_bytes()).unwrap();
        assert_eq!(exiftool["AbsoluteAltitude"], "+100.25");
        assert_eq!(exiftool["GimbalPitchDegree"], "-30.5");
        assert_eq!(exiftool.len(), 2);
        // Another namespace's property of the same name is not DJI's.
        let other = AS_EXIFTOOL.replace("www.dji.com", "example.com");
        assert!(drone_dji(other.as_bytes()).unwrap().is_empty());
        assert!(drone_dji(b"<a><b></a>").is_err());
    }

    #[test]
    fn finds_the_packet_among_the_segments() {
        let mut jpeg = vec![0xFF, 0xD8];
        let exif = b"Exif\0\0xxxx";
        jpeg.extend([0xFF, 0xE1]);
        jpeg.extend(((exif.len() + 2) as u16).to_be_bytes());
        jpeg.extend(exif);
        let xmp = [XMP_SIGNATURE, AS_DJI.as_bytes()].concat();
        jpeg.extend([0xFF, 0xE1]);
        jpeg.extend(((xmp.len() + 2) as u16).to_be_bytes());
        jpeg.extend(&xmp);
        jpeg.extend([0xFF, 0xDA, 0, 2]);
        assert_eq!(packet(&jpeg), Some(AS_DJI.as_bytes()));
        assert_eq!(packet(&jpeg[..jpeg.len() - 20]), None);
        assert_eq!(packet(b"not a jpeg"), None);
    }
}
