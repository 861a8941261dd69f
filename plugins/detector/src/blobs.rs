//! Finding aircraft in a frame: small compact regions clearly darker than their
//! surroundings (an aircraft against the sky or the ground).
//!
//! 1. Luminance (Rec. 601) of each pixel.
//! 2. The local background: the mean luminance over a `(2r+1)²` window
//!    (`imageproc::filter::box_filter`, edges replicated).
//! 3. Foreground: pixels darker than their background by more than `threshold`.
//! 4. Connected components (8-connected) of the foreground
//!    (`imageproc::region_labelling::connected_components`).
//! 5. Parts of one aircraft joined: components that could each be (part of) an aircraft
//!    (compact, not larger than `max_size_px`) whose bounding boxes lie within
//!    `join_gap` times the smaller one's larger side of each other are one blob. A near
//!    quadcopter is its rotors, which the darker-than-background test separates where its
//!    lighter body lies between them; as separate blobs each would be an aircraft of
//!    half the size beside the true one.
//! 6. Kept: components of at least `min_area_px` pixels whose bounding box is compact
//!    (aspect ratio at most `max_aspect`, filled at least `min_fill`) and not larger than
//!    `max_size_px`: lines (the horizon, field edges, grid lines) are long and thin,
//!    aircraft are not.
//!
//! The centre of a blob is its contrast-weighted centroid (sub-pixel).

use imageproc::filter::box_filter;
use imageproc::image::{GrayImage, Luma};
use imageproc::region_labelling::{Connectivity, connected_components};

/// Detection tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlobParams {
    /// Half the background window, pixels.
    pub background_radius_px: u32,
    /// Darker than the background by more than this (0–255 luminance).
    pub threshold: f64,
    /// Smallest blob, pixels.
    pub min_area_px: usize,
    /// Largest bounding-box side, pixels.
    pub max_size_px: u32,
    /// Largest bounding-box aspect ratio (long side / short side).
    pub max_aspect: f64,
    /// Smallest fraction of the bounding box the blob fills.
    pub min_fill: f64,
    /// Components closer than this times the smaller one's larger side are one blob
    /// (see the module docs).
    pub join_gap: f64,
}

impl Default for BlobParams {
    fn default() -> Self {
        BlobParams {
            background_radius_px: 12,
            threshold: 50.0,
            min_area_px: 6,
            max_size_px: 160,
            max_aspect: 3.0,
            min_fill: 0.3,
            join_gap: 0.5,
        }
    }
}

/// One aircraft-like blob.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// Bounding box left edge, pixels.
    pub x: u32,
    /// Top edge, pixels.
    pub y: u32,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Contrast-weighted centroid, pixels from the left edge (pixel centres at +0.5).
    pub cx: f64,
    /// Centroid, pixels from the top edge.
    pub cy: f64,
    /// Pixels in the blob.
    pub area: usize,
    /// Mean darkness below the background, luminance units.
    pub contrast: f64,
}

/// Luminance of RGB8 pixels.
pub fn luminance(rgb: &[u8]) -> Vec<f32> {
    rgb.chunks_exact(3)
        .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
        .collect()
}

/// The aircraft-like blobs of an RGB8 frame (`width × height`), strongest first.
pub fn find_blobs(rgb: &[u8], width: u32, height: u32, p: &BlobParams) -> Vec<Blob> {
    let (w, h) = (width as usize, height as usize);
    if rgb.len() < w * h * 3 || w == 0 || h == 0 {
        return Vec::new();
    }
    let l = luminance(&rgb[..w * h * 3]);
    let gray: Vec<u8> = l
        .iter()
        .map(|v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    let Some(gray) = GrayImage::from_raw(width, height, gray) else {
        return Vec::new();
    };
    let r = p.background_radius_px;
    let bg = box_filter(&gray, r, r);
    let dark: Vec<f32> = l
        .iter()
        .zip(bg.as_raw())
        .map(|(v, b)| f32::from(*b) - v)
        .collect();
    let fg = GrayImage::from_fn(width, height, |x, y| {
        Luma([u8::from(f64::from(dark[y as usize * w + x as usize]) > p.threshold) * 255])
    });
    let labels = connected_components(&fg, Connectivity::Eight, Luma([0u8]));
    let n = labels.as_raw().iter().copied().max().unwrap_or(0) as usize;
    let mut acc = vec![Acc::EMPTY; n + 1];
    for (x, y, px) in labels.enumerate_pixels() {
        let label = px[0] as usize;
        if label == 0 {
            continue;
        }
        let wgt = f64::from(dark[y as usize * w + x as usize]);
        acc[label].add(x, y, wgt);
    }
    let acc = join_parts(acc.into_iter().skip(1).filter(|a| a.area > 0), p);
    let mut blobs: Vec<Blob> = acc
        .into_iter()
        .filter_map(|a| {
            let (bw, bh) = a.size();
            let fill = a.area as f64 / (f64::from(bw) * f64::from(bh));
            (a.area >= p.min_area_px && a.compact(p) && fill >= p.min_fill).then(|| Blob {
                x: a.x0,
                y: a.y0,
                width: bw,
                height: bh,
                cx: a.sx / a.sw,
                cy: a.sy / a.sw,
                area: a.area,
                contrast: a.sw / a.area as f64,
            })
        })
        .collect();
    blobs.sort_by(|a, b| (b.contrast * b.area as f64).total_cmp(&(a.contrast * a.area as f64)));
    blobs
}

/// A component's box, area and darkness-weighted sums.
#[derive(Clone, Copy)]
struct Acc {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    area: usize,
    sw: f64,
    sx: f64,
    sy: f64,
}

impl Acc {
    const EMPTY: Acc = Acc {
        x0: u32::MAX,
        y0: u32::MAX,
        x1: 0,
        y1: 0,
        area: 0,
        sw: 0.0,
        sx: 0.0,
        sy: 0.0,
    };

    fn add(&mut self, x: u32, y: u32, wgt: f64) {
        self.x0 = self.x0.min(x);
        self.y0 = self.y0.min(y);
        self.x1 = self.x1.max(x);
        self.y1 = self.y1.max(y);
        self.area += 1;
        self.sw += wgt;
        self.sx += wgt * (f64::from(x) + 0.5);
        self.sy += wgt * (f64::from(y) + 0.5);
    }

    fn absorb(&mut self, o: &Acc) {
        self.x0 = self.x0.min(o.x0);
        self.y0 = self.y0.min(o.y0);
        self.x1 = self.x1.max(o.x1);
        self.y1 = self.y1.max(o.y1);
        self.area += o.area;
        self.sw += o.sw;
        self.sx += o.sx;
        self.sy += o.sy;
    }

    /// Bounding box width and height, pixels.
    fn size(&self) -> (u32, u32) {
        (self.x1 - self.x0 + 1, self.y1 - self.y0 + 1)
    }

    /// Shaped like (part of) an aircraft: not larger than `max_size_px`, aspect ratio at
    /// most `max_aspect`.
    fn compact(&self, p: &BlobParams) -> bool {
        let (bw, bh) = self.size();
        bw.max(bh) <= p.max_size_px && f64::from(bw.max(bh)) / f64::from(bw.min(bh)) <= p.max_aspect
    }

    /// Empty pixels between the two boxes along the axis where they are farthest apart (0
    /// when they touch or overlap).
    fn gap_px(&self, o: &Acc) -> u32 {
        let gx = self.x0.max(o.x0).saturating_sub(self.x1.min(o.x1) + 1);
        let gy = self.y0.max(o.y0).saturating_sub(self.y1.min(o.y1) + 1);
        gx.max(gy)
    }
}

/// Joins the parts of one aircraft (step 5 of the module docs) until no two compact
/// components are within reach of each other; the rest pass through unchanged.
fn join_parts(components: impl Iterator<Item = Acc>, p: &BlobParams) -> Vec<Acc> {
    let (mut parts, mut out): (Vec<Acc>, Vec<Acc>) = components.partition(|a| a.compact(p));
    loop {
        let mut joined = false;
        let mut i = 0;
        while i < parts.len() {
            let mut j = i + 1;
            while j < parts.len() {
                let (a, b) = (&parts[i], &parts[j]);
                let side = |c: &Acc| f64::from(c.size().0.max(c.size().1));
                let reach = p.join_gap * side(a).min(side(b));
                if f64::from(a.gap_px(b)) <= reach {
                    let b = parts.swap_remove(j);
                    parts[i].absorb(&b);
                    joined = true;
                } else {
                    j += 1;
                }
            }
            i += 1;
        }
        if !joined {
            break;
        }
    }
    out.append(&mut parts);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sky(w: u32, h: u32) -> Vec<u8> {
        let mut px = Vec::with_capacity((w * h * 3) as usize);
        for y in 0..h {
            for _ in 0..w {
                // A vertical gradient like the camera's sky.
                let t = f64::from(y) / f64::from(h);
                px.extend_from_slice(&[
                    (60.0 + 145.0 * t) as u8,
                    (115.0 + 107.0 * t) as u8,
                    (190.0 + 48.0 * t) as u8,
                ]);
            }
        }
        px
    }

    fn disc(px: &mut [u8], w: u32, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let h = px.len() as u32 / 3 / w;
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (f64::from(x) + 0.5 - cx, f64::from(y) + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    let i = ((y * w + x) * 3) as usize;
                    px[i..i + 3].copy_from_slice(&c);
                }
            }
        }
    }

    #[test]
    fn finds_a_dark_disc_at_its_centre_and_nothing_in_an_empty_sky() {
        let (w, h) = (160, 120);
        let mut px = sky(w, h);
        assert!(find_blobs(&px, w, h, &BlobParams::default()).is_empty());
        disc(&mut px, w, 50.3, 70.8, 4.0, [30, 30, 35]);
        let blobs = find_blobs(&px, w, h, &BlobParams::default());
        assert_eq!(blobs.len(), 1, "{blobs:?}");
        let b = blobs[0];
        assert!(
            (b.cx - 50.3).abs() < 0.3 && (b.cy - 70.8).abs() < 0.3,
            "{b:?}"
        );
        assert!((7..=9).contains(&b.width), "{b:?}");
    }

    #[test]
    fn the_rotors_of_a_near_quadcopter_are_one_blob_and_two_aircraft_stay_two() {
        let (w, h) = (160, 120);
        let mut px = sky(w, h);
        // The camera's near intruder (radius 14 px): four black rotors around a grey
        // body that is not dark enough against its own surroundings to join them.
        let (cx, cy, rr) = (60.0, 60.0, 14.0);
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let (x, y) = (cx + sx * rr * 0.55, cy + sy * rr * 0.55 * 0.5);
            disc(&mut px, w, x, y, rr * 0.4, [20, 20, 22]);
        }
        disc(&mut px, w, cx, cy, rr * 0.38, [150, 150, 155]);
        // A far aircraft 30 px to its right.
        disc(&mut px, w, 120.0, 62.0, 3.0, [20, 20, 22]);
        let blobs = find_blobs(&px, w, h, &BlobParams::default());
        assert_eq!(blobs.len(), 2, "{blobs:?}");
        let near = blobs.iter().find(|b| b.cx < 100.0).expect("the near one");
        assert!(
            (near.cx - cx).abs() < 0.5 && (near.cy - cy).abs() < 0.5,
            "{near:?}"
        );
        // As wide as its rotors reach: 2 × (0.55 + 0.4) × 14 px.
        assert!((25..=28).contains(&near.width), "{near:?}");
        let far = blobs.iter().find(|b| b.cx > 100.0).expect("the far one");
        assert!((far.cx - 120.0).abs() < 0.5, "{far:?}");
    }

    #[test]
    fn lines_are_not_aircraft() {
        let (w, h) = (160, 120);
        let mut px = sky(w, h);
        // A long dark horizontal line, 2 px thick.
        for y in 60..62 {
            for x in 10..150 {
                let i = ((y * w + x) * 3) as usize;
                px[i..i + 3].copy_from_slice(&[40, 60, 40]);
            }
        }
        assert!(find_blobs(&px, w, h, &BlobParams::default()).is_empty());
    }
}
