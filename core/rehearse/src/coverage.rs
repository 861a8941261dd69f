//! Survey coverage: the fraction of a survey's polygon its vehicles' cameras saw at the
//! planned overlap. The polygon is rasterised (cells at most [`MAX_CELL_M`] wide, a cell
//! inside when its centre is); each vehicle's path at the survey's altitude (within
//! [`ALTITUDE_TOLERANCE_M`]) sweeps a band of half-width `F (1 − o/2) / 2` around it,
//! where `F` is the camera's footprint across the lane at that height and `o` the planned
//! overlap: neighbouring lanes flown exactly overlap by `F o / 2`, so a point counts as
//! seen at the planned overlap even when the two lanes beside it drift by a quarter of
//! the overlap each. With a `lane_spacing_m` and no camera, the band is the lane's own
//! width (no overlap, no tolerance).

use skein_mission::plan::Survey;
use skein_model::geo::Ned;
use skein_model::geofence::polygon;
use std::collections::BTreeMap;

/// Widest raster cell, metres.
pub const MAX_CELL_M: f64 = 1.0;
/// A vehicle within this of the survey's altitude films the ground, metres.
pub const ALTITUDE_TOLERANCE_M: f64 = 2.0;

/// One survey's raster and what has been seen of it.
#[derive(Debug, Clone)]
pub struct Coverage {
    altitude_m: f64,
    half_width_m: f64,
    cell_m: f64,
    origin: [f64; 2],
    cols: usize,
    rows: usize,
    /// Per cell: inside the polygon, and seen.
    inside: Vec<bool>,
    seen: Vec<bool>,
    inside_cells: usize,
    /// Each vehicle's last sample on the survey's altitude.
    last: BTreeMap<String, [f64; 2]>,
}

impl Coverage {
    /// The raster of survey `s`.
    pub fn new(s: &Survey) -> Self {
        let (footprint_m, overlap) = match (s.lane_spacing_m, s.camera) {
            (Some(l), _) => (l, 0.0),
            (None, Some(c)) => (
                c.lane_spacing_m(s.altitude_m) / (1.0 - c.overlap),
                c.overlap,
            ),
            (None, None) => (0.0, 0.0),
        };
        let half_width_m = footprint_m * (1.0 - overlap / 2.0) / 2.0;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &s.polygon {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let cell_m = (half_width_m / 4.0).clamp(0.25, MAX_CELL_M);
        let rows = ((hi[0] - lo[0]) / cell_m).ceil().max(1.0) as usize;
        let cols = ((hi[1] - lo[1]) / cell_m).ceil().max(1.0) as usize;
        let mut inside = vec![false; rows * cols];
        for r in 0..rows {
            for c in 0..cols {
                let centre = [
                    lo[0] + (r as f64 + 0.5) * cell_m,
                    lo[1] + (c as f64 + 0.5) * cell_m,
                ];
                inside[r * cols + c] = polygon::inside(&s.polygon, centre);
            }
        }
        let inside_cells = inside.iter().filter(|i| **i).count();
        Coverage {
            altitude_m: s.altitude_m,
            half_width_m,
            cell_m,
            origin: lo,
            cols,
            rows,
            seen: vec![false; rows * cols],
            inside,
            inside_cells,
            last: BTreeMap::new(),
        }
    }

    /// Vehicle `id` is at `p` (swarm frame): at the survey's altitude, the band from its
    /// last sample to here is seen; off it, its path breaks.
    pub fn sample(&mut self, id: &str, p: Ned) {
        if (-p.down_m - self.altitude_m).abs() > ALTITUDE_TOLERANCE_M {
            self.last.remove(id);
            return;
        }
        let here = [p.north_m, p.east_m];
        let from = self.last.insert(id.to_string(), here).unwrap_or(here);
        self.sweep(from, here);
    }

    /// Marks the cells within the band's half-width of segment `a`–`b`.
    fn sweep(&mut self, a: [f64; 2], b: [f64; 2]) {
        let w = self.half_width_m;
        let cell = |x: f64, o: f64| ((x - o) / self.cell_m).floor();
        let r0 = cell(a[0].min(b[0]) - w, self.origin[0]).max(0.0) as usize;
        let c0 = cell(a[1].min(b[1]) - w, self.origin[1]).max(0.0) as usize;
        let r1 = (cell(a[0].max(b[0]) + w, self.origin[0]).max(-1.0) + 1.0) as usize;
        let c1 = (cell(a[1].max(b[1]) + w, self.origin[1]).max(-1.0) + 1.0) as usize;
        for r in r0..r1.min(self.rows) {
            for c in c0..c1.min(self.cols) {
                let i = r * self.cols + c;
                if self.seen[i] || !self.inside[i] {
                    continue;
                }
                let centre = [
                    self.origin[0] + (r as f64 + 0.5) * self.cell_m,
                    self.origin[1] + (c as f64 + 0.5) * self.cell_m,
                ];
                let q = polygon::nearest_on_segment(a, b, centre);
                if polygon::distance(q, centre) <= w {
                    self.seen[i] = true;
                }
            }
        }
    }

    /// The fraction of the polygon seen, 0 to 1.
    pub fn fraction(&self) -> f64 {
        let seen = self
            .seen
            .iter()
            .zip(&self.inside)
            .filter(|(s, i)| **s && **i)
            .count();
        seen as f64 / self.inside_cells.max(1) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn survey() -> Survey {
        serde_json::from_value(serde_json::json!({
            "polygon": [[0, 0], [0, 40], [20, 40], [20, 0]], "altitude_m": 10,
            "lane_spacing_m": 10
        }))
        .unwrap()
    }

    #[test]
    fn lanes_flown_cover_the_area_and_a_missed_one_shows() {
        let mut c = Coverage::new(&survey());
        let fly = |c: &mut Coverage, id: &str, north: f64| {
            for east in 0..=40 {
                c.sample(id, Ned::new(north, f64::from(east), -10.0));
            }
        };
        fly(&mut c, "uav-1", 5.0);
        assert!((c.fraction() - 0.5).abs() < 0.02, "{}", c.fraction());
        // Too high: films nothing.
        for east in 0..=40 {
            c.sample("uav-3", Ned::new(15.0, f64::from(east), -20.0));
        }
        assert!((c.fraction() - 0.5).abs() < 0.02, "{}", c.fraction());
        fly(&mut c, "uav-2", 15.0);
        assert!(c.fraction() > 0.99, "{}", c.fraction());
    }
}
