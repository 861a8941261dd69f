//! This process's clock against its peers' (the other agents and coordinators of the
//! swarm), so that the age of a stamped target, report or mirror from another host is
//! its age, whatever that host's clock says.
//!
//! Every process stamps what it sends with its wall clock ([`crate::protocol::wall_us`]),
//! and the receiver moves positions on by their age. Across hosts the clocks differ: a
//! companion computer without GNSS time may be off by hundreds of milliseconds, and a
//! target 300 ms "older" than it is puts a vehicle 1.5 m off at 5 m/s. So processes
//! exchange clock samples (`skein_dds::clocks`, the NTP exchange over the swarm's own
//! link): each sample carries its send time and, for each peer, the send time of the
//! peer's last sample and when it arrived. From one exchange with peer P
//! (`t0` sent here, `t1` received there, `t2` sent there, `t3` received here):
//!
//! - offset (P's clock minus this one's) = `((t1 − t0) + (t2 − t3)) / 2`;
//! - round trip = `(t3 − t0) − (t2 − t1)`, and the offset is off by at most half of it.
//!
//! [`PeerClocks`] keeps the last [`WINDOW`] exchanges per peer and trusts the one with the
//! shortest round trip (queueing delays only ever lengthen one leg, so the fastest
//! exchange is the most symmetric); its uncertainty is half that round trip.
//! [`PeerClocks::to_local_us`] converts a peer's stamp into this clock.

use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::sync::Mutex;
use std::sync::PoisonError;

/// Exchanges kept per peer.
pub const WINDOW: usize = 16;

/// A peer's clock as this process estimates it (`clocks` in `GET /api/v1/coordinator`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ClockOffset {
    /// The peer's clock minus this process's, milliseconds.
    pub offset_ms: f64,
    /// Half the round trip of the exchange the offset comes from: the offset is within
    /// this of the truth, milliseconds.
    pub uncertainty_ms: f64,
    /// Exchanges it rests on (at most [`WINDOW`]).
    pub exchanges: usize,
    /// Seconds since the last exchange (this clock).
    pub age_s: f64,
}

/// One exchange: offset and round trip, µs, and when it completed (this clock, µs).
#[derive(Debug, Clone, Copy)]
struct Exchange {
    offset_us: i64,
    round_trip_us: i64,
    at_us: u64,
}

/// The clocks of this process's peers (see the module docs). Shared by the roles that
/// receive stamps and the API that shows them.
#[derive(Debug, Default)]
pub struct PeerClocks {
    peers: Mutex<BTreeMap<String, VecDeque<Exchange>>>,
}

impl PeerClocks {
    /// Records an exchange with `peer`: `t0` this process sent, `t1` the peer received,
    /// `t2` the peer sent, `t3` this process received (µs, each on its own host's wall
    /// clock). Exchanges with a negative round trip (a clock stepped meanwhile) are
    /// dropped.
    pub fn exchange(&self, peer: &str, t0: u64, t1: u64, t2: u64, t3: u64) {
        let (t0, t1, t2, t3) = (t0 as i64, t1 as i64, t2 as i64, t3 as i64);
        let round_trip_us = (t3 - t0) - (t2 - t1);
        if round_trip_us < 0 {
            return;
        }
        let offset_us = ((t1 - t0) + (t2 - t3)) / 2;
        let mut peers = self.peers.lock().unwrap_or_else(PoisonError::into_inner);
        let q = peers.entry(peer.to_string()).or_default();
        if q.len() == WINDOW {
            q.pop_front();
        }
        q.push_back(Exchange {
            offset_us,
            round_trip_us,
            at_us: t3 as u64,
        });
    }

    /// The exchange trusted for `peer` (shortest round trip of the window).
    fn best(q: &VecDeque<Exchange>) -> Option<Exchange> {
        q.iter().min_by_key(|e| e.round_trip_us).copied()
    }

    /// `peer`'s clock minus this one's, µs, if any exchange was made.
    pub fn offset_us(&self, peer: &str) -> Option<i64> {
        let peers = self.peers.lock().unwrap_or_else(PoisonError::into_inner);
        peers.get(peer).and_then(Self::best).map(|e| e.offset_us)
    }

    /// `stamp_us` of `peer`'s clock in this clock (unchanged when no exchange with it was
    /// made yet: the clocks are then assumed the same).
    pub fn to_local_us(&self, peer: &str, stamp_us: u64) -> u64 {
        match self.offset_us(peer) {
            Some(o) => (stamp_us as i64 - o).max(0) as u64,
            None => stamp_us,
        }
    }

    /// Every peer's estimate at `now_us` (this clock), by id.
    pub fn snapshot(&self, now_us: u64) -> BTreeMap<String, ClockOffset> {
        let peers = self.peers.lock().unwrap_or_else(PoisonError::into_inner);
        peers
            .iter()
            .filter_map(|(id, q)| {
                let best = Self::best(q)?;
                let last = q.back()?.at_us;
                Some((
                    id.clone(),
                    ClockOffset {
                        offset_ms: best.offset_us as f64 / 1e3,
                        uncertainty_ms: best.round_trip_us as f64 / 2e3,
                        exchanges: q.len(),
                        age_s: now_us.saturating_sub(last) as f64 / 1e6,
                    },
                ))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An exchange with a peer whose clock is `offset_us` ahead, one-way delays `out_us`
    /// (here → there) and `back_us`, starting at `t0` here, turned around in 40 ms.
    fn exchange(c: &PeerClocks, t0: u64, offset_us: i64, out_us: u64, back_us: u64) {
        let t1 = (t0 + out_us) as i64 + offset_us;
        let t2 = t1 + 40_000;
        let t3 = (t2 - offset_us) as u64 + back_us;
        c.exchange("agent-2", t0, t1 as u64, t2 as u64, t3);
    }

    #[test]
    fn the_fastest_exchange_gives_the_offset_within_half_its_round_trip() {
        let c = PeerClocks::default();
        assert_eq!(c.to_local_us("agent-2", 5_000), 5_000, "no exchange yet");
        // 300 ms ahead; symmetric 2 ms legs, then exchanges with 30 ms of queueing on one leg.
        exchange(&c, 1_000_000, 300_000, 30_000, 2_000);
        exchange(&c, 2_000_000, 300_000, 2_000, 2_000);
        exchange(&c, 3_000_000, 300_000, 2_000, 45_000);
        let s = c.snapshot(3_100_000);
        let o = &s["agent-2"];
        assert!((o.offset_ms - 300.0).abs() < 1e-9, "{o:?}");
        assert!((o.uncertainty_ms - 2.0).abs() < 1e-9, "{o:?}");
        assert_eq!(o.exchanges, 3);
        // A stamp of its clock in this one: 300 ms earlier.
        assert_eq!(c.to_local_us("agent-2", 10_300_000), 10_000_000);
        // A skewed queueing leg alone makes an error of half the asymmetry, within the
        // uncertainty it states.
        let c = PeerClocks::default();
        exchange(&c, 1_000_000, -300_000, 30_000, 2_000);
        let o = &c.snapshot(1_100_000)["agent-2"];
        assert!((o.offset_ms + 300.0 - 14.0).abs() < 1e-9, "{o:?}");
        assert!((o.offset_ms + 300.0).abs() <= o.uncertainty_ms, "{o:?}");
    }

    #[test]
    fn only_the_last_exchanges_count_and_a_stepped_clock_is_dropped() {
        let c = PeerClocks::default();
        exchange(&c, 1_000_000, 100_000, 1_000, 1_000);
        for k in 0..WINDOW as u64 {
            exchange(&c, 2_000_000 + k * 500_000, 200_000, 5_000, 5_000);
        }
        // The fast exchange at 100 ms has left the window.
        assert_eq!(c.offset_us("agent-2"), Some(200_000));
        c.exchange("agent-2", 10, 20, 30, 5); // received before it was sent
        assert_eq!(c.snapshot(0)["agent-2"].exchanges, WINDOW);
    }
}
