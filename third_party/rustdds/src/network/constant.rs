// These constants are from RTPS spec Section 9.6.2.3 Default Port Numbers
const PB: u16 = 7400;
const DG: u16 = 250;
const PG: u16 = 2;

const D0: u16 = 0;
const D1: u16 = 10;
const D2: u16 = 1;
const D3: u16 = 11;

pub const fn spdp_well_known_multicast_port(domain_id: u16) -> u16 {
  PB + DG * domain_id + D0
}

pub const fn spdp_well_known_unicast_port(domain_id: u16, participant_id: u16) -> u16 {
  PB + DG * domain_id + D1 + PG * participant_id
}

pub const fn user_traffic_multicast_port(domain_id: u16) -> u16 {
  PB + DG * domain_id + D2
}

pub const fn user_traffic_unicast_port(domain_id: u16, participant_id: u16) -> u16 {
  PB + DG * domain_id + D3 + PG * participant_id
}

/// Default number of same-host participant slots probed by unicast SPDP
/// "localhost peers". SPDP is additionally sent to
/// `127.0.0.1:spdp_well_known_unicast_port(domain, pid)` for
/// `pid in 0..SPDP_LOCALHOST_PEER_COUNT`, so that two participants on the same
/// host discover each other even when there is no external network and
/// multicast on the loopback interface is unavailable (the Linux default for
/// `lo`). See `src/rtps/loopback_same_host_design.md`.
///
/// skein patch: this is the margin *past our own participant id*, not a fixed
/// range ([`localhost_spdp_peer_slots`]). With a fixed range of 12, two
/// participants whose ids were both 12 or more never probed each other, so a
/// host with more than a dozen participants (no multicast on `lo`) did not
/// assemble.
pub const SPDP_LOCALHOST_PEER_COUNT: u16 = 12;

/// Participant ids a participant may take: RTPS spec 2.5 Section 9.6.2.3 (ports
/// of a domain run out past 120 participants; the participant-id search stops
/// there too).
pub const MAX_PARTICIPANT_ID_COUNT: u16 = 120;

/// How many same-host participant slots (`0..n`) participant `own_participant_id`
/// probes by unicast SPDP (skein patch): every id below its own (each was taken
/// when it chose its own, the lowest free one, so it was started earlier and
/// may not have heard of this one), and [`SPDP_LOCALHOST_PEER_COUNT`] above it
/// (a lower id freed and taken again by a later participant). Of any two
/// participants, the one with the higher id probes the other, whose quick SPDP
/// response then closes the loop.
pub const fn localhost_spdp_peer_slots(own_participant_id: u16) -> u16 {
  let n = own_participant_id.saturating_add(1 + SPDP_LOCALHOST_PEER_COUNT);
  if n < MAX_PARTICIPANT_ID_COUNT {
    n
  } else {
    MAX_PARTICIPANT_ID_COUNT
  }
}

#[cfg(test)]
mod tests {
  use super::*;

  #[test]
  fn every_pair_of_same_host_participants_is_probed_by_one_of_them() {
    for low in 0..MAX_PARTICIPANT_ID_COUNT {
      for high in low + 1..MAX_PARTICIPANT_ID_COUNT {
        assert!(
          low < localhost_spdp_peer_slots(high),
          "participant {high} does not probe {low}"
        );
      }
    }
    assert_eq!(localhost_spdp_peer_slots(0), 13);
    assert_eq!(localhost_spdp_peer_slots(20), 33);
    assert_eq!(localhost_spdp_peer_slots(119), MAX_PARTICIPANT_ID_COUNT);
  }
}
