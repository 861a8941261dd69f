//! Finding aircraft in a frame: small compact regions clearly darker than their
//! surroundings (an aircraft against the sky or the ground).
//!
//! 1. Luminance (Rec. 601) of each pixel.
//! 2. The local background: the mean luminance over a `(2r+1)²` window, from a summed-area
//!    table (so the cost does not depend on `r`).
//! 3. Foreground: pixels darker than their background by more than `threshold`.
//! 4. Connected components (8-connected) of the foreground, by breadth-first labelling.
//! 5. Kept: components of at least `min_area_px` pixels whose bounding box is compact
//!    (aspect ratio at most `max_aspect`, filled at least `min_fill`) and not larger than
//!    `max_size_px`: lines (the horizon, field edges, grid lines) are long and thin,
//!    aircraft are not.
//!
//! The centre of a blob is its contrast-weighted centroid (sub-pixel).

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

/// Mean of `l` over the window of half-size `r` around each pixel (clipped at the edges).
pub fn box_mean(l: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    // Summed-area table with a zero row and column in front.
    let mut sat = vec![0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0f64;
        for x in 0..w {
            row += f64::from(l[y * w + x]);
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let s = sat[y1 * (w + 1) + x1] - sat[y0 * (w + 1) + x1] - sat[y1 * (w + 1) + x0]
                + sat[y0 * (w + 1) + x0];
            out[y * w + x] = (s / ((y1 - y0) * (x1 - x0)) as f64) as f32;
        }
    }
    out
}

/// The aircraft-like blobs of an RGB8 frame (`width × height`), strongest first.
pub fn find_blobs(rgb: &[u8], width: u32, height: u32, p: &BlobParams) -> Vec<Blob> {
    let (w, h) = (width as usize, height as usize);
    if rgb.len() < w * h * 3 || w == 0 || h == 0 {
        return Vec::new();
    }
    let l = luminance(&rgb[..w * h * 3]);
    let bg = box_mean(&l, w, h, p.background_radius_px as usize);
    let dark: Vec<f32> = l.iter().zip(&bg).map(|(v, b)| b - v).collect();
    let fg: Vec<bool> = dark.iter().map(|d| f64::from(*d) > p.threshold).collect();
    let mut seen = vec![false; w * h];
    let mut blobs = Vec::new();
    let mut queue = std::collections::VecDeque::new();
    for start in 0..w * h {
        if !fg[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        queue.push_back(start);
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        let (mut area, mut sw, mut sx, mut sy) = (0usize, 0f64, 0f64, 0f64);
        while let Some(i) = queue.pop_front() {
            let (x, y) = (i % w, i / w);
            let wgt = f64::from(dark[i]);
            area += 1;
            sw += wgt;
            sx += wgt * (x as f64 + 0.5);
            sy += wgt * (y as f64 + 0.5);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if fg[j] && !seen[j] {
                        seen[j] = true;
                        queue.push_back(j);
                    }
                }
            }
        }
        let (bw, bh) = ((x1 - x0 + 1) as u32, (y1 - y0 + 1) as u32);
        let aspect = f64::from(bw.max(bh)) / f64::from(bw.min(bh));
        let fill = area as f64 / (f64::from(bw) * f64::from(bh));
        if area >= p.min_area_px
            && bw.max(bh) <= p.max_size_px
            && aspect <= p.max_aspect
            && fill >= p.min_fill
        {
            blobs.push(Blob {
                x: x0 as u32,
                y: y0 as u32,
                width: bw,
                height: bh,
                cx: sx / sw,
                cy: sy / sw,
                area,
                contrast: sw / area as f64,
            });
        }
    }
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
