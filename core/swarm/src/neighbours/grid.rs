//! The spatial index of the neighbour board: a uniform grid of horizontal cells, built once
//! per control period from every place and shared by every vehicle's separation query.
//!
//! A swarm is spread over an area and a few metres of altitude, and a separation query asks
//! for the places within a few metres of one point (the separation plus the distance the
//! vehicles can close in one step, see `SetpointShaper::reach_m`). So the places are keyed
//! by their north/east cell of [`CELL_M`], sorted by key once (each row of cells is then one
//! contiguous run), and a query looks up one run per row its circle touches and checks the
//! distance in 3-D. Building is a sort of small keys (an R*-tree's bulk load of a thousand
//! vehicles cost ten times more, every period); a query is a binary search per row.

use skein_model::geo::Ned;

/// Side of a cell, metres: a query within the separation of a hovering or cruising vehicle
/// (3–6 m) touches at most two rows of two cells.
pub(super) const CELL_M: f64 = 8.0;

/// A query whose circle spans more rows than this scans every place instead.
const MAX_ROWS: i64 = 64;

/// One place in the grid.
#[derive(Debug, Clone, Copy)]
struct Cellular {
    key: u64,
    /// What the caller indexed it by (its place in the caller's list).
    data: u32,
    point: [f64; 3],
}

/// Places keyed by their horizontal cell (see the module docs).
#[derive(Debug, Default)]
pub(super) struct Grid {
    /// Sorted by `key`: row by row (north), west to east within a row.
    places: Vec<Cellular>,
}

/// The cell of a coordinate (metres). `as` saturates, so a far-off or non-finite
/// coordinate still gets a cell, in order.
fn cell(v_m: f64) -> i32 {
    (v_m / CELL_M).floor() as i32
}

/// The key of cell (`row`, `column`): ordered as the pair (the sign bits flipped so that
/// unsigned order is signed order).
fn key(row: i32, column: i32) -> u64 {
    (u64::from(row as u32 ^ 0x8000_0000) << 32) | u64::from(column as u32 ^ 0x8000_0000)
}

impl Grid {
    /// Indexes `places` (each a NED position, metres, and the caller's number for it).
    pub(super) fn build(places: impl Iterator<Item = (Ned, u32)>) -> Grid {
        let mut places: Vec<Cellular> = places
            .map(|(p, data)| Cellular {
                key: key(cell(p.north_m), cell(p.east_m)),
                data,
                point: [p.north_m, p.east_m, p.down_m],
            })
            .collect();
        places.sort_unstable_by_key(|c| c.key);
        Grid { places }
    }

    /// Appends to `found` the number of every place at most `radius_m` from `center` (in
    /// no particular order). An infinite radius gives every place.
    pub(super) fn within(&self, center: Ned, radius_m: f64, found: &mut Vec<u32>) {
        if radius_m.is_infinite() && radius_m > 0.0 {
            found.extend(self.places.iter().map(|c| c.data));
            return;
        }
        let c = [center.north_m, center.east_m, center.down_m];
        let r = radius_m;
        let near = |p: &Cellular| {
            let (dn, de, dd) = (p.point[0] - c[0], p.point[1] - c[1], p.point[2] - c[2]);
            dn * dn + de * de + dd * dd <= r * r && r >= 0.0
        };
        let (row0, row1) = (cell(c[0] - r), cell(c[0] + r));
        let (column0, column1) = (cell(c[1] - r), cell(c[1] + r));
        if i64::from(row1) - i64::from(row0) >= MAX_ROWS {
            found.extend(self.places.iter().filter(|p| near(p)).map(|p| p.data));
            return;
        }
        for row in row0..=row1 {
            let (first, last) = (key(row, column0), key(row, column1));
            let start = self.places.partition_point(|p| p.key < first);
            found.extend(
                self.places[start..]
                    .iter()
                    .take_while(|p| p.key <= last)
                    .filter(|p| near(p))
                    .map(|p| p.data),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A query finds exactly what measuring every place finds: places scattered over
    /// cells of both signs, on cell borders, at other altitudes, with small, large, zero,
    /// negative and infinite radii, and centres far outside the swarm.
    #[test]
    fn a_query_finds_exactly_the_places_within_its_radius() {
        let mut rng = SmallRng::seed_from_u64(11);
        let mut next = || rng.random::<f64>();
        let mut points: Vec<Ned> = (0..400)
            .map(|_| {
                Ned::new(
                    next() * 120.0 - 60.0,
                    next() * 120.0 - 60.0,
                    -10.0 - next() * 6.0,
                )
            })
            .collect();
        // On cell borders.
        points.push(Ned::new(CELL_M, -CELL_M, -10.0));
        points.push(Ned::new(0.0, 0.0, -10.0));
        let grid = Grid::build(points.iter().enumerate().map(|(i, p)| (*p, i as u32)));
        let mut centres: Vec<Ned> = (0..200)
            .map(|_| Ned::new(next() * 140.0 - 70.0, next() * 140.0 - 70.0, -12.0))
            .collect();
        centres.push(Ned::new(CELL_M, -CELL_M + 3.0, -10.0));
        centres.push(Ned::new(1e9, -1e9, 0.0));
        for (k, centre) in centres.iter().enumerate() {
            for r in [0.0, 3.0, 3.3, 8.0, 17.5, 2000.0, -1.0, f64::INFINITY] {
                let mut found = Vec::new();
                grid.within(*centre, r, &mut found);
                found.sort_unstable();
                let expected: Vec<u32> = points
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| (**p - *centre).norm() <= r)
                    .map(|(i, _)| i as u32)
                    .collect();
                assert_eq!(found, expected, "centre {k} {centre:?}, radius {r}");
            }
        }
        assert!(
            centres.iter().any(|c| {
                let mut f = Vec::new();
                grid.within(*c, 3.3, &mut f);
                f.len() > 1
            }),
            "some query finds several places"
        );
    }
}
