//! Unit tests of the receiver's parts on synthetic clocks: the fix state machine's
//! delays, PX4's inject queue, the error model's statistics per state and its
//! transitions. The RTCM3 framing is tested through the vehicle's MAVLink input
//! (`core/sim/tests/gnss.rs`), with frames made by rtcm-rs.

use super::error::{ErrorModel, FixFigures};
use super::fix::{GnssFix, RtkState, RtkTiming};
use super::rtcm::{InjectQueue, RtcmCounts, is_observation};
use std::time::{Duration, Instant};

/// `t0 + s` seconds.
fn at(t0: Instant, s: f64) -> Instant {
    t0 + Duration::from_secs_f64(s)
}

/// Somewhere on the Earth's surface (PX4's SITL home), ECEF m.
fn antenna() -> [f64; 3] {
    crate::config::PX4_SITL_HOME.to_ecef()
}

/// `antenna()` moved `d` metres along x.
fn base_at(d: f64) -> [f64; 3] {
    let a = antenna();
    [a[0] + d, a[1], a[2]]
}

/// Runs `rtk` from `from_s` to `to_s` in 10 ms steps, with an observation frame every
/// second when `corrections`; returns every change of fix as (time s, fix).
fn run(
    rtk: &mut RtkState,
    t0: Instant,
    from_s: f64,
    to_s: f64,
    corrections: bool,
) -> Vec<(f64, GnssFix)> {
    let mut changes = Vec::new();
    let mut last = rtk.fix();
    let steps = ((to_s - from_s) * 100.0).round() as usize;
    for k in 0..steps {
        let t = from_s + k as f64 * 0.01;
        if corrections && k.is_multiple_of(100) {
            rtk.on_observations(at(t0, t));
        }
        let fix = rtk.update(at(t0, t));
        if fix != last {
            changes.push((t, fix));
            last = fix;
        }
    }
    changes
}

fn close(changes: &[(f64, GnssFix)], want: &[(f64, GnssFix)]) -> bool {
    changes.len() == want.len()
        && changes
            .iter()
            .zip(want)
            .all(|(c, w)| c.1 == w.1 && (c.0 - w.0).abs() < 0.015)
}

#[test]
fn fix_follows_the_corrections_at_the_configured_delays() {
    use GnssFix::*;
    let timing = RtkTiming {
        rtk_float_after_s: 4.0,
        rtk_fixed_after_s: 10.0,
        rtk_hold_s: 3.0,
        dgnss_timeout_s: 30.0,
    };
    let t0 = Instant::now();
    let mut rtk = RtkState::new(timing, antenna());
    // Observations from 0 s, the base position only at 2 s: the RTK clock starts then.
    let mut changes = run(&mut rtk, t0, 0.0, 2.0, true);
    rtk.on_base(at(t0, 2.0), base_at(1000.0));
    changes.extend(run(&mut rtk, t0, 2.0, 40.0, true));
    assert!(
        close(&changes, &[(6.0, RtkFloat), (16.0, RtkFixed)]),
        "{changes:?}"
    );
    // Last observation at 39 s: fixed held until 42 s, float until 69 s.
    let changes = run(&mut rtk, t0, 40.0, 80.0, false);
    assert!(
        close(&changes, &[(42.01, RtkFloat), (69.01, Fix3d)]),
        "{changes:?}"
    );
    assert!(rtk.age(at(t0, 80.0)) > Some(Duration::from_secs(40)));
    // Back at 80 s, from a 3D fix: float after 4 s, fixed after 10 more.
    let changes = run(&mut rtk, t0, 80.0, 100.0, true);
    assert!(
        close(&changes, &[(84.0, RtkFloat), (94.0, RtkFixed)]),
        "{changes:?}"
    );
    // A 10 s gap (under the DGNSS timeout): float meanwhile, fixed 14 s after the return.
    let mut changes = run(&mut rtk, t0, 100.0, 110.0, false);
    changes.extend(run(&mut rtk, t0, 110.0, 130.0, true));
    assert!(
        close(&changes, &[(102.01, RtkFloat), (124.0, RtkFixed)]),
        "{changes:?}"
    );
    // A different base: RTK starts over (float held while the new one converges).
    rtk.on_base(at(t0, 130.0), base_at(2000.0));
    let changes = run(&mut rtk, t0, 130.0, 150.0, true);
    assert!(
        close(&changes, &[(130.0, RtkFloat), (144.0, RtkFixed)]),
        "{changes:?}"
    );
}

#[test]
fn no_rtk_without_a_base_or_with_one_too_far() {
    let t0 = Instant::now();
    let mut rtk = RtkState::new(RtkTiming::default(), antenna());
    assert!(run(&mut rtk, t0, 0.0, 60.0, true).is_empty(), "no base: 3D");
    rtk.on_base(at(t0, 60.0), base_at(60_000.0));
    assert!(run(&mut rtk, t0, 60.0, 120.0, true).is_empty(), "60 km: 3D");
    assert_eq!(rtk.baseline_m().map(f64::round), Some(60_000.0));
}

#[test]
fn observation_message_numbers() {
    for n in [
        1001, 1004, 1009, 1012, 1071, 1074, 1077, 1087, 1097, 1107, 1117, 1127, 1137,
    ] {
        assert!(is_observation(n), "{n}");
    }
    for n in [
        1005, 1006, 1007, 1008, 1013, 1019, 1033, 1070, 1078, 1080, 1230, 4072,
    ] {
        assert!(!is_observation(n), "{n}");
    }
}

#[test]
fn inject_queue_keeps_eight_and_drains_once_per_driver_cycle() {
    let t0 = Instant::now();
    let mut q = InjectQueue::default();
    let mut counts = RtcmCounts::default();
    for i in 0..11u8 {
        q.publish(&[i], &mut counts);
    }
    assert_eq!(counts.inject_queue_overruns, 3);
    let drained = q.drain_due(t0);
    let firsts: Vec<u8> = drained.iter().map(|d| d[0]).collect();
    assert_eq!(firsts, (3..11).collect::<Vec<u8>>(), "the oldest are lost");
    q.publish(&[42], &mut counts);
    let ms = |n| t0 + Duration::from_millis(n);
    assert!(q.drain_due(ms(40)).is_empty(), "next cycle 50 ms later");
    assert_eq!(q.drain_due(ms(50)), vec![vec![42]]);
}

/// Horizontal and vertical RMS of the error in `fix` over `window_s`, after `warmup_s`
/// in it (the error model stepped at `dt`; its discretisation is exact for any step).
fn rms(seed: u64, fix: GnssFix, warmup_s: f64, window_s: f64) -> (f64, f64) {
    let dt = 0.1;
    let mut m = ErrorModel::new(seed);
    for _ in 0..(warmup_s / dt) as usize {
        m.step(dt, fix, 1000.0);
    }
    let (mut h, mut v, mut n) = (0.0, 0.0, 0.0);
    for _ in 0..(window_s / dt) as usize {
        m.step(dt, fix, 1000.0);
        let e = m.error();
        h += e.north_m.powi(2) + e.east_m.powi(2);
        v += e.down_m.powi(2);
        n += 1.0;
    }
    ((h / n).sqrt(), (v / n).sqrt())
}

#[test]
fn error_rms_of_each_state_is_in_its_band() {
    for seed in [1, 2, 3] {
        let (h3, v3) = rms(seed, GnssFix::Fix3d, 0.0, 3600.0);
        let (hf, vf) = rms(seed, GnssFix::RtkFloat, 20.0, 1800.0);
        let (hx, vx) = rms(seed, GnssFix::RtkFixed, 20.0, 600.0);
        eprintln!(
            "seed {seed}: RMS h/v 3D {h3:.2}/{v3:.2} m, float {hf:.3}/{vf:.3} m, fixed \
             {hx:.4}/{vx:.4} m"
        );
        assert!((0.5..5.0).contains(&h3) && v3 > 0.5, "3D {h3} {v3}");
        assert!(
            (0.1..0.8).contains(&hf) && (0.1..1.2).contains(&vf),
            "float {hf} {vf}"
        );
        assert!(
            (0.005..=0.03).contains(&hx) && (0.01..=0.04).contains(&vx),
            "fixed {hx} {vx}"
        );
    }
}

#[test]
fn reported_accuracy_of_each_state() {
    let acc = |fix, baseline| {
        let f = FixFigures::of(fix, baseline);
        (f.h_acc_mm(), f.v_acc_mm())
    };
    assert_eq!(acc(GnssFix::Fix3d, 0.0), (1802, 1911));
    assert_eq!(acc(GnssFix::RtkFloat, 0.0), (354, 400));
    assert_eq!(acc(GnssFix::RtkFixed, 0.0), (17, 22));
    // 1 ppm of a 10 km baseline: 1 cm more.
    assert_eq!(acc(GnssFix::RtkFixed, 10_000.0), (29, 37));
}

#[test]
fn transitions_converge_within_seconds_without_jumps() {
    let dt = 0.01;
    let mut m = ErrorModel::new(7);
    for _ in 0..10_000 {
        m.step(dt, GnssFix::Fix3d, 0.0);
    }
    let before = m.error();
    assert!(
        before.horizontal_norm() > 0.3,
        "a 3D error to converge from"
    );
    let mut biggest_step: f64 = 0.0;
    let mut prev = before;
    for k in 1..=3000 {
        m.step(dt, GnssFix::RtkFixed, 0.0);
        biggest_step = biggest_step.max((m.error() - prev).norm());
        prev = m.error();
        if k == 1200 {
            assert!(
                m.error().norm() < 0.08,
                "12 s after the fix: {:?} (was {before:?})",
                m.error()
            );
        }
    }
    // The convergence is a first-order lag of CONVERGE_TAU_S: at most |e| / tau per s.
    let bound = before.norm() / super::CONVERGE_TAU_S * dt * 1.1 + 0.005;
    assert!(biggest_step < bound, "step {biggest_step} m > {bound}");
    // Back to 3D: the error grows without a jump either.
    let from = m.error();
    m.step(dt, GnssFix::Fix3d, 0.0);
    assert!((m.error() - from).norm() < 0.1);
}

#[test]
fn same_seed_same_error_different_seed_different() {
    let run = |seed| {
        let mut m = ErrorModel::new(seed);
        let mut trace = Vec::new();
        for k in 0..500 {
            let fix = if k < 250 {
                GnssFix::Fix3d
            } else {
                GnssFix::RtkFloat
            };
            m.step(0.01, fix, 0.0);
            trace.push(m.error());
        }
        trace
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}
