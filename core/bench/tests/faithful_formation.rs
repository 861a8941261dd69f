//! A formation on the PX4-faithful simulated multicopter (`skein_bench::rehearsal` with
//! `AirframeKind::Px4`: PX4 v1.16's position-control cascade on SIH-like physics, the
//! same model `skein sim` flies), with PX4's estimator noise on: a wedge of five behind a
//! virtual leader cruising at 5 m/s and orbiting at 5 m/s (radius 40 m) keeps its RMS
//! slot error under 0.3 m (about 0.2 m of that is PX4's own hover wander) and every pair
//! at the minimum separation. Virtual time: deterministic, a few seconds of CPU.

use skein_bench::rehearsal::{AirframeKind, Rehearsal, RehearsalConfig};
use skein_model::formation::Shape;
use skein_model::geo::Ned;
use skein_swarm::formation::{FormationFrame, FormationSpec, VIRTUAL};

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

#[test]
fn a_wedge_holds_its_slots_cruising_and_orbiting_at_5_m_s_with_estimator_noise() {
    let mut config = RehearsalConfig::new(5);
    config.airframe = AirframeKind::Px4 {
        estimator_noise: true,
    };
    let mut r = Rehearsal::new(config);
    r.set_formation(FormationSpec {
        shape: Shape::Wedge,
        spacing_m: 6.0,
        leader: Some(VIRTUAL.into()),
        heading_deg: 0.0,
        altitude_m: Some(12.0),
        frame: FormationFrame::World,
        offsets: vec![],
        standoff_m: None,
    });
    assert!(
        r.run_until(120.0, |r| {
            let s = r.status();
            s.transition_progress.is_none() && s.rms_error_m.is_some_and(|e| e < 0.3)
        }),
        "did not converge: {:?}",
        r.status()
    );
    let cruise = r.cruise_to(Ned::new(80.0, 0.0, -12.0), 5.0).unwrap();
    let orbit = r
        .orbit(Ned::new(80.0, 40.0, -12.0), 40.0, 5.0, 30.0)
        .unwrap();
    let s = r.stats();
    println!(
        "{}",
        serde_json::json!({"cruise_rms_m": mean(&cruise), "orbit_rms_m": mean(&orbit),
                           "min_separation_m": s.min_separation_m, "samples": [cruise.len(), orbit.len()]})
    );
    assert!(cruise.len() >= 20 && orbit.len() >= 50, "too few samples");
    assert!(mean(&cruise) < 0.3, "cruise RMS {}", mean(&cruise));
    assert!(mean(&orbit) < 0.3, "orbit RMS {}", mean(&orbit));
    assert_eq!(s.separation_violations, 0, "{s:?}");
    assert!(s.min_separation_m >= 3.0, "{s:?}");
}
