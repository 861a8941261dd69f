//! Formation changes in virtual time (the real engine and shapers, see
//! `skein_bench::rehearsal`): 100 seeded random changes of shape, spacing, heading, frame
//! and altitude, with the virtual leader moving, never bring two vehicles closer than the
//! minimum separation and never take one out of the geofence.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use skein_bench::rehearsal::{Rehearsal, RehearsalConfig};
use skein_model::formation::Shape;
use skein_model::geo::Ned;
use skein_model::safety::Geofence;
use skein_swarm::formation::{FormationFrame, FormationSpec, LeaderMotion, VIRTUAL};

/// Every shape but `custom` (all of them fly 8 vehicles).
fn shapes() -> Vec<Shape> {
    Shape::ALL
        .into_iter()
        .filter(|s| *s != Shape::Custom)
        .collect()
}

fn settled(r: &Rehearsal) -> bool {
    let s = r.status();
    s.transition_progress.is_none() && s.pending.is_none() && s.rms_error_m.is_some_and(|e| e < 0.3)
}

#[test]
fn hundred_seeded_random_changes_keep_separation_and_fence() {
    random_changes(VIRTUAL, 100);
}

/// Behind a leader vehicle, which keeps slot 0: followers whose path would cross it climb
/// over it.
#[test]
fn random_changes_behind_a_leader_vehicle_keep_separation() {
    random_changes("uav-1", 40);
}

fn random_changes(leader: &str, changes: usize) {
    let mut config = RehearsalConfig::new(8);
    config.fence = Geofence {
        radius_m: 150.0,
        max_altitude_m: 40.0,
        min_altitude_m: 5.0,
        ..Geofence::default()
    };
    let mut r = Rehearsal::new(config);
    let seed = std::env::var("SKEIN_REHEARSAL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5ce1);
    let mut rng = SmallRng::seed_from_u64(seed);
    let shapes = shapes();
    let mut converge_s = Vec::new();
    for change in 0..changes {
        let spec = FormationSpec {
            shape: shapes[rng.random_range(0..shapes.len())],
            spacing_m: rng.random_range(5.0..9.0),
            leader: Some(leader.into()),
            heading_deg: rng.random_range(0.0..360.0),
            altitude_m: Some(rng.random_range(8.0..30.0)),
            frame: if rng.random_bool(0.5) {
                FormationFrame::World
            } else {
                FormationFrame::Leader
            },
            offsets: vec![],
            standoff_m: None,
        };
        let t0 = r.time_s();
        r.set_formation(spec.clone());
        // Every other change, the virtual leader sets off somewhere (up to the fence's
        // edge, so that slots get clamped) while the formation reshapes.
        if change % 2 == 1 {
            let bearing = rng.random_range(0.0..std::f64::consts::TAU);
            let dist = rng.random_range(0.0..140.0);
            let target = Ned::new(dist * bearing.cos(), dist * bearing.sin(), -20.0);
            r.set_motion(LeaderMotion::GoTo {
                target,
                speed_m_s: rng.random_range(1.0..5.0),
            })
            .unwrap();
        }
        // Change again before the previous one is over, now and then.
        let wait = if change % 7 == 3 { 2.0 } else { 120.0 };
        let ok = r.run_until(wait, settled);
        assert!(
            ok || wait < 100.0,
            "change {change} ({spec:?}) did not settle: {:?}",
            r.status()
        );
        if ok {
            converge_s.push(r.time_s() - t0);
        }
        let s = r.stats();
        assert_eq!(
            s.separation_violations, 0,
            "change {change} ({spec:?}): two vehicles {:.2} m apart",
            s.min_separation_m
        );
        assert_eq!(s.fence_violations, 0, "change {change}: out of the fence");
    }
    let s = r.stats();
    assert!(s.min_separation_m >= 3.0);
    converge_s.sort_by(f64::total_cmp);
    eprintln!(
        "{{\"leader\": \"{leader}\", \"changes\": {changes}, \"min_separation_m\": {:.3}, \"fence_clamps\": {}, \"converge_s_p50\": {:.1}, \"converge_s_max\": {:.1}, \"virtual_s\": {:.0}}}",
        s.min_separation_m,
        s.fence_clamps,
        converge_s[converge_s.len() / 2],
        converge_s.last().unwrap(),
        r.time_s()
    );
}
