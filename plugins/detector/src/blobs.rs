//! Finding aircraft in a frame: small compact regions clearly darker than their
//! surroundings (an aircraft against the sky or the ground).
//!
//! 1. Luminance (Rec. 601) of each pixel.
//! 2. The local background: the mean luminance over a `(2r+1)²` window
//!    (`imageproc::filter::box_filter`, edges replicated).
//! 3. Foreground: pixels darker than their background by more than `threshold`.
//! 4. Connected components (8-connected) of the foreground
//!    (`imageproc::region_labelling::connected_components`).
//! 5. Kept: components of at least `min_area_px` pixels whose bounding box is compact
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
    // Per label (0: background): box, area, darkness-weighted sums.
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
    let n = labels.as_raw().iter().copied().max().unwrap_or(0) as usize;
    let empty = Acc {
        x0: u32::MAX,
        y0: u32::MAX,
        x1: 0,
        y1: 0,
        area: 0,
        sw: 0.0,
        sx: 0.0,
        sy: 0.0,
    };
    let mut acc = vec![empty; n + 1];
    for (x, y, px) in labels.enumerate_pixels() {
        let label = px[0] as usize;
        if label == 0 {
            continue;
        }
        let a = &mut acc[label];
        let wgt = f64::from(dark[y as usize * w + x as usize]);
        a.x0 = a.x0.min(x);
        a.y0 = a.y0.min(y);
        a.x1 = a.x1.max(x);
        a.y1 = a.y1.max(y);
        a.area += 1;
        a.sw += wgt;
        a.sx += wgt * (f64::from(x) + 0.5);
        a.sy += wgt * (f64::from(y) + 0.5);
    }
    let mut blobs: Vec<Blob> = acc
        .into_iter()
        .skip(1)
        .filter(|a| a.area > 0)
        .filter_map(|a| {
            let (bw, bh) = (a.x1 - a.x0 + 1, a.y1 - a.y0 + 1);
            let aspect = f64::from(bw.max(bh)) / f64::from(bw.min(bh));
            let fill = a.area as f64 / (f64::from(bw) * f64::from(bh));
            (a.area >= p.min_area_px
                && bw.max(bh) <= p.max_size_px
                && aspect <= p.max_aspect
                && fill >= p.min_fill)
                .then(|| Blob {
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
