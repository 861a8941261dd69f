//! Per-frame camera metadata carried inside the JPEG, as drone cameras do (DJI's XMP
//! `drone-dji:GimbalYawDegree` …): where the camera was and where it looked when the frame
//! was taken, so whoever processes the frame later (the `detector` plugin) turns pixels
//! into bearings with the pose of *that* frame, not the vehicle's pose when it reads it.
//!
//! Carried as an XMP packet in an APP1 segment (`http://ns.adobe.com/xap/1.0/\0` header),
//! attributes of one `rdf:Description` in the `skein` namespace ([`XMP_NAMESPACE`]):
//! `skein:Frame`, `skein:StampUs` (wall-clock µs), `skein:North`, `skein:East`,
//! `skein:Down` (camera position, swarm-frame NED, m), `skein:Azimuth` (optical axis,
//! degrees clockwise from north), `skein:Elevation` (degrees above the horizontal, no
//! roll), `skein:FocalPx` (focal length in pixels; principal point at the image centre,
//! square pixels), `skein:Width`, `skein:Height` (pixels).

/// The XMP namespace of skein's camera metadata.
pub const XMP_NAMESPACE: &str = "urn:skein:camera:1";

/// Header of an XMP APP1 segment (before the packet).
pub const XMP_APP1_HEADER: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";

/// Metadata of one frame (see the module docs for units and frames).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameMeta {
    /// Frame number of the camera instance, from 1.
    pub frame: u64,
    /// Capture time, wall-clock microseconds since the Unix epoch.
    pub stamp_us: u64,
    /// Camera position north, swarm frame, m.
    pub north_m: f64,
    /// Camera position east, m.
    pub east_m: f64,
    /// Camera position down, m.
    pub down_m: f64,
    /// Optical axis azimuth, degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Optical axis elevation, degrees above the horizontal.
    pub elevation_deg: f64,
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
}

impl FrameMeta {
    /// The XMP packet (UTF-8 XML).
    pub fn to_xmp(&self) -> String {
        format!(
            "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF \
             xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\"><rdf:Description \
             xmlns:skein=\"{XMP_NAMESPACE}\" skein:Frame=\"{}\" skein:StampUs=\"{}\" \
             skein:North=\"{}\" skein:East=\"{}\" skein:Down=\"{}\" skein:Azimuth=\"{}\" \
             skein:Elevation=\"{}\" skein:FocalPx=\"{}\" skein:Width=\"{}\" \
             skein:Height=\"{}\"/></rdf:RDF></x:xmpmeta>",
            self.frame,
            self.stamp_us,
            self.north_m,
            self.east_m,
            self.down_m,
            self.azimuth_deg,
            self.elevation_deg,
            self.focal_px,
            self.width_px,
            self.height_px
        )
    }

    /// The APP1 segment's payload: [`XMP_APP1_HEADER`] then the packet.
    pub fn to_app1(&self) -> Vec<u8> {
        let mut v = XMP_APP1_HEADER.to_vec();
        v.extend_from_slice(self.to_xmp().as_bytes());
        v
    }

    /// Reads the metadata from an XMP packet (with or without the APP1 header).
    ///
    /// # Errors
    /// Not UTF-8, or an attribute missing or not a number (named).
    pub fn from_xmp(packet: &[u8]) -> Result<FrameMeta, String> {
        let packet = packet.strip_prefix(XMP_APP1_HEADER).unwrap_or(packet);
        let text = std::str::from_utf8(packet).map_err(|_| "XMP packet is not UTF-8")?;
        fn attr<T: std::str::FromStr>(text: &str, name: &str) -> Result<T, String> {
            let key = format!("skein:{name}=\"");
            let start = text
                .find(&key)
                .ok_or_else(|| format!("frame metadata: no skein:{name}"))?
                + key.len();
            let end = text[start..]
                .find('"')
                .ok_or_else(|| format!("frame metadata: skein:{name} is not closed"))?;
            text[start..start + end]
                .parse()
                .map_err(|_| format!("frame metadata: skein:{name} is not a number"))
        }
        Ok(FrameMeta {
            frame: attr(text, "Frame")?,
            stamp_us: attr(text, "StampUs")?,
            north_m: attr(text, "North")?,
            east_m: attr(text, "East")?,
            down_m: attr(text, "Down")?,
            azimuth_deg: attr(text, "Azimuth")?,
            elevation_deg: attr(text, "Elevation")?,
            focal_px: attr(text, "FocalPx")?,
            width_px: attr(text, "Width")?,
            height_px: attr(text, "Height")?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_xmp() {
        let m = FrameMeta {
            frame: 7,
            stamp_us: 1_700_000_000_123_456,
            north_m: 1.25,
            east_m: -3.5,
            down_m: -10.0,
            azimuth_deg: 359.5,
            elevation_deg: -2.25,
            focal_px: 415.2,
            width_px: 640,
            height_px: 480,
        };
        assert_eq!(FrameMeta::from_xmp(&m.to_app1()), Ok(m));
        assert_eq!(FrameMeta::from_xmp(m.to_xmp().as_bytes()), Ok(m));
        let err = FrameMeta::from_xmp(b"<x/>").unwrap_err();
        assert!(err.contains("skein:Frame"), "{err}");
    }
}
