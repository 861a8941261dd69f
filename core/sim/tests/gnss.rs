//! The GNSS receiver and its RTK corrections through the vehicle's MAVLink input:
//! GPS_RTCM_DATA fragments as PX4 v1.16 takes them, the RTCM3 frames the receiver finds
//! in them (a 1005 made by rtcm-rs, a GPS MSM7 laid out with its CRC-24Q), the fix they
//! drive and what the vehicle reports of it (GPS_RAW_INT, the truth); the error model's
//! wander of a hovering vehicle (`gnss_wander`); with the option off, not one trajectory
//! changed. On the virtual clock ([`VirtualVehicle`]); one test over real UDP.
#![allow(deprecated)]

mod common;

use common::*;
use skein_mavlink::MavMessage;
use skein_mavlink::dialect::*;
use skein_model::geo::{GeoPoint, Ned, NedFrame};
use skein_sim::{
    PX4_SITL_HOME, RtcmCounts, RtkTiming, SimConfig, SimTruth, TelemetryProfile, VirtualVehicle,
    WindConfig, client,
};
use std::time::Duration;

/// A virtual vehicle at PX4's SITL home (EKF fix after 0.2 s), `tweak`ed.
fn vehicle(tweak: impl FnOnce(&mut SimConfig)) -> VirtualVehicle {
    let mut cfg = SimConfig {
        ekf_fix_delay_s: 0.2,
        ..SimConfig::default()
    };
    tweak(&mut cfg);
    VirtualVehicle::new(&cfg)
}

/// What a run saw: every change of the truth's fix type (time s, fix type), and every
/// GPS_RAW_INT (time s, the message).
#[derive(Default)]
struct Seen {
    changes: Vec<(f64, u8)>,
    gps: Vec<(f64, GPS_RAW_INT_DATA)>,
    last_fix: u8,
}

impl Seen {
    fn record(&mut self, t: f64, truth: &SimTruth, msgs: &[(f64, MavMessage)]) {
        if truth.gnss.fix_type != self.last_fix {
            self.changes.push((t, truth.gnss.fix_type));
            self.last_fix = truth.gnss.fix_type;
        }
        for (t, m) in msgs {
            if let MavMessage::GPS_RAW_INT(g) = m {
                self.gps.push((*t, g.clone()));
            }
        }
    }

    /// The fix type changes after `from_s`, times rounded to 10 ms.
    fn changes_after(&self, from_s: f64) -> Vec<(f64, u8)> {
        self.changes
            .iter()
            .filter(|c| c.0 > from_s)
            .map(|&(t, f)| ((t * 100.0).round() / 100.0, f))
            .collect()
    }

    /// (fix_type, h_acc, v_acc) of every GPS_RAW_INT between `from_s` and `to_s`.
    fn reports(&self, from_s: f64, to_s: f64) -> Vec<(u8, u32, u32)> {
        let mut r: Vec<_> = self
            .gps
            .iter()
            .filter(|(t, _)| (from_s..to_s).contains(t))
            .map(|(_, g)| (g.fix_type as u8, g.h_acc, g.v_acc))
            .collect();
        r.dedup();
        r
    }
}

/// Sends every message of `msgs` to `v` (what it answers is of no interest here).
fn send_all(v: &mut VirtualVehicle, msgs: &[MavMessage]) {
    for m in msgs {
        v.send(m);
    }
}

/// Steps `v` until `until_s`, sending `caster`'s next epoch at each whole second.
fn run(v: &mut VirtualVehicle, until_s: f64, mut caster: Option<&mut Caster>, seen: &mut Seen) {
    while v.time_s() + 1e-9 < until_s {
        let centis = (v.time_s() * 100.0).round() as u64;
        if let Some(c) = caster.as_deref_mut()
            && centis.is_multiple_of(100)
        {
            let epoch = c.epoch();
            send_all(v, &epoch);
        }
        let msgs = v.step();
        seen.record(v.time_s(), &v.truth(), &msgs);
    }
}

#[test]
fn corrections_in_fragments_give_float_then_fixed_and_fall_back_when_they_stop() {
    let mut v = vehicle(|_| {});
    let mut caster = Caster::at(PX4_SITL_HOME);
    let mut seen = Seen::default();
    run(&mut v, 2.0, None, &mut seen);
    assert_eq!(v.truth().gnss.corrections_age_s, None);
    // Corrections from 2 s to 39 s: the first frames reach the receiver at the GPS
    // driver's next cycle (2.01 s); float 5 s later, fixed 15 s after that.
    run(&mut v, 40.0, Some(&mut caster), &mut seen);
    assert_eq!(seen.changes_after(1.0), vec![(7.01, 5), (22.01, 6)]);
    assert_eq!(
        seen.reports(1.0, 6.9),
        vec![(3, 900, 1780)],
        "3D fix: PX4 SIH's figures without the error model"
    );
    assert_eq!(seen.reports(7.1, 21.9), vec![(5, 354, 400)], "RTK float");
    assert_eq!(seen.reports(22.1, 40.0), vec![(6, 17, 22)], "RTK fixed");
    let age = v.truth().gnss.corrections_age_s.expect("corrections seen");
    assert!((0.9..1.0).contains(&age), "age {age}");
    // They stop (last frames at 39.01 s): fixed held 5 s, float until u-blox's 60 s
    // DGNSS timeout, then a 3D fix.
    run(&mut v, 110.0, None, &mut seen);
    assert_eq!(seen.changes_after(40.0), vec![(44.02, 5), (99.02, 3)]);
    // Back at 110 s, from the 3D fix: float, then fixed, at the same delays.
    run(&mut v, 140.0, Some(&mut caster), &mut seen);
    assert_eq!(seen.changes_after(110.0), vec![(115.01, 5), (130.01, 6)]);
    // A 20 s gap, within the DGNSS timeout: float meanwhile, fixed 20 s after the return.
    run(&mut v, 160.0, None, &mut seen);
    run(&mut v, 185.0, Some(&mut caster), &mut seen);
    assert_eq!(seen.changes_after(140.0), vec![(144.02, 5), (180.01, 6)]);
    assert_eq!(
        v.stats().rtcm,
        RtcmCounts {
            gps_rtcm_data: 93 * 4,
            bytes_to_receiver: 93 * (25 + 446),
            frames_ok: 93 * 2,
            observation_frames: 93,
            base_position_frames: 93,
            ..RtcmCounts::default()
        },
        "93 epochs of a 1005 (one message) and an MSM7 (three fragments)"
    );
}

#[test]
fn test_frames_are_good_rtcm3_and_split_by_mavlink_rules() {
    // The 1005 from rtcm-rs's encoder and the hand-laid MSM7 carry the CRC-24Q rtcm-rs
    // checks; the MSM7 is one RTCM message over three GPS_RTCM_DATA fragments.
    let mut caster = Caster::at(PX4_SITL_HOME);
    let [base, msm] = caster.epoch_frames();
    assert_eq!(frame_number(&base), 1005);
    assert_eq!(frame_number(&msm), 1077);
    let n = base.len() - 3;
    assert_eq!(crc24q(&base[..n]).to_be_bytes()[1..], base[n..]);
    assert_eq!((base.len(), msm.len()), (25, 446));
    let msgs = client::gps_rtcm_data(&msm, 9).expect("fits");
    let parts: Vec<(u8, u8)> = msgs
        .iter()
        .map(|m| match m {
            MavMessage::GPS_RTCM_DATA(d) => (d.flags, d.len),
            other => panic!("{other:?}"),
        })
        .collect();
    // flags: fragmented, fragment id 0/1/2, sequence 9.
    assert_eq!(parts, vec![(0x49, 180), (0x4B, 180), (0x4D, 86)]);
    let single = client::gps_rtcm_data(&base, 9).expect("fits");
    assert!(matches!(&single[..], [MavMessage::GPS_RTCM_DATA(d)] if d.flags == 0x48));
    // A full last fragment is followed by an empty one; over 720 bytes is refused.
    assert_eq!(client::gps_rtcm_data(&[0; 360], 0).expect("fits").len(), 3);
    assert!(client::gps_rtcm_data(&[0; 721], 0).is_err());
}

#[test]
fn a_lost_fragment_or_a_bad_crc_drops_the_message_and_the_fix_does_not_advance() {
    let mut v = vehicle(|_| {});
    let mut caster = Caster::at(PX4_SITL_HOME);
    let mut seen = Seen::default();
    run(&mut v, 1.0, None, &mut seen);
    // 20 epochs, each MSM7 missing its middle fragment (as over a lossy link).
    for _ in 0..20 {
        let frames = caster.epoch_frames();
        let [base, mut msm] =
            <[Vec<MavMessage>; 2]>::try_from(caster.messages(&frames)).expect("two sequences");
        msm.remove(1);
        send_all(&mut v, &base);
        send_all(&mut v, &msm);
        let until = v.time_s() + 1.0;
        run(&mut v, until, None, &mut seen);
    }
    let counts = v.stats().rtcm;
    eprintln!("lost middle fragments, 20 epochs: {counts:?}");
    // Each broken MSM7 (266 of its 446 bytes) fails its CRC once the next epoch's bytes
    // complete its length and becomes garbage; the 20th still waits for more bytes. Every
    // 1005 is found again behind it.
    assert_eq!(counts.observation_frames, 0);
    assert_eq!(counts.crc_failures, 19, "{counts:?}");
    assert_eq!(counts.garbage_bytes, 19 * 266, "{counts:?}");
    assert_eq!(counts.base_position_frames, 20, "{counts:?}");
    assert_eq!(v.truth().gnss.corrections_age_s, None);
    // A whole MSM7 with one flipped payload byte: dropped too.
    let [base, mut msm] = caster.epoch_frames();
    msm[100] ^= 0x10;
    let msgs = caster.messages(&[base, msm]);
    send_all(&mut v, &msgs.concat());
    let until = v.time_s() + 1.0;
    run(&mut v, until, None, &mut seen);
    let after = v.stats().rtcm;
    assert!(after.crc_failures > counts.crc_failures, "{after:?}");
    assert_eq!(after.observation_frames, 0);
    assert!(seen.changes_after(1.0).is_empty(), "{:?}", seen.changes);
    // Good epochs again: the receiver resynchronises, float within the delay.
    let start = v.time_s();
    run(&mut v, start + 8.0, Some(&mut caster), &mut seen);
    let float_at = seen
        .changes_after(start)
        .first()
        .copied()
        .expect("RTK float");
    assert_eq!(float_at.1, 5);
    assert!(
        float_at.0 - start <= 7.0,
        "float {:.2} s after",
        float_at.0 - start
    );
    eprintln!(
        "resynchronised: float {:.2} s after the first good epoch",
        float_at.0 - start
    );
}

#[test]
fn malformed_and_bursting_gps_rtcm_data_are_counted() {
    let mut v = vehicle(|_| {});
    let mut seen = Seen::default();
    run(&mut v, 1.0, None, &mut seen);
    // len 200 > 180: counted and dropped.
    send_all(
        &mut v,
        &[MavMessage::GPS_RTCM_DATA(GPS_RTCM_DATA_DATA {
            flags: 0,
            len: 200,
            data: [0xD3; 180],
        })],
    );
    // Three epochs (12 messages) at once: uORB gps_inject_data holds 8, the first epoch
    // is lost whole, the other two arrive intact.
    let mut caster = Caster::at(PX4_SITL_HOME);
    let burst: Vec<MavMessage> = (0..3).flat_map(|_| caster.epoch()).collect();
    send_all(&mut v, &burst);
    run(&mut v, 1.2, None, &mut seen);
    let c = v.stats().rtcm;
    assert_eq!(c.gps_rtcm_data_malformed, 1);
    assert_eq!(c.gps_rtcm_data, 12);
    assert_eq!(c.inject_queue_overruns, 4);
    assert_eq!((c.frames_ok, c.crc_failures, c.garbage_bytes), (4, 0, 0));
}

/// RMS of the horizontal and vertical components of `v`.
fn rms(v: &[Ned]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let h = v
        .iter()
        .map(|e| e.north_m.powi(2) + e.east_m.powi(2))
        .sum::<f64>()
        / n;
    let d = v.iter().map(|e| e.down_m.powi(2)).sum::<f64>() / n;
    (h.sqrt(), d.sqrt())
}

fn ned(a: [f64; 3]) -> Ned {
    Ned::new(a[0], a[1], a[2])
}

/// What a hover sampled every 0.1 s: the receiver's error, the truth's and the report's
/// (LOCAL_POSITION_NED) offsets from the hold point, and the GPS_RAW_INT position's
/// offset from the truth.
#[derive(Default)]
struct Hover {
    error: Vec<Ned>,
    truth_off: Vec<Ned>,
    reported_off: Vec<Ned>,
    gps_minus_truth_and_error: Vec<Ned>,
}

/// Hovers `v` at `hold` in OFFBOARD for `secs` (setpoints at 50 Hz, a GCS heartbeat each
/// second, `caster`'s epoch each second when given), sampling after `skip_s`.
fn hover(
    v: &mut VirtualVehicle,
    hold: Ned,
    secs: f64,
    skip_s: f64,
    mut caster: Option<&mut Caster>,
) -> Hover {
    let sp = client::setpoint(client::POSITION_YAW, hold, Ned::ZERO, Ned::ZERO, 0.0);
    let (start, mut out) = (v.time_s(), Hover::default());
    let mut reported = hold;
    let mut k = 0u64;
    while v.time_s() < start + secs {
        if k.is_multiple_of(50) {
            v.send(&client::gcs_heartbeat());
            if let Some(c) = caster.as_deref_mut() {
                let epoch = c.epoch();
                send_all(v, &epoch);
            }
        }
        v.send(&sp);
        let msgs = v.step();
        k += 1;
        let truth = v.truth();
        let frame = NedFrame::new(truth.local_origin);
        for (_, m) in &msgs {
            match m {
                MavMessage::LOCAL_POSITION_NED(p) => {
                    reported = Ned::new(p.x.into(), p.y.into(), p.z.into());
                }
                MavMessage::GPS_RAW_INT(g) if v.time_s() > start + skip_s => {
                    let at = frame.to_ned(&GeoPoint::from_mavlink(g.lat, g.lon, g.alt));
                    let off = at - truth.local_ned_m - ned(truth.gnss.error_ned_m);
                    out.gps_minus_truth_and_error.push(off);
                }
                _ => {}
            }
        }
        if v.time_s() > start + skip_s && k.is_multiple_of(5) {
            out.error.push(ned(truth.gnss.error_ned_m));
            out.truth_off.push(truth.local_ned_m - hold);
            out.reported_off.push(reported - hold);
        }
    }
    out
}

#[test]
fn the_wander_moves_the_true_position_while_the_estimate_holds_the_setpoint() {
    let mut v = vehicle(|cfg| {
        cfg.gnss_wander = true;
        cfg.seed = 3;
        cfg.telemetry = TelemetryProfile::Swarm;
    });
    let hold = Ned::new(0.0, 0.0, -10.0);
    assert!(v.take_off_offboard(10.0, 15.0), "did not take off");
    // Ten minutes with a 3D fix: metres of slow wander.
    let h3 = hover(&mut v, hold, 600.0, 0.0, None);
    let (err_h, err_v) = rms(&h3.error);
    let (truth_h, _) = rms(&h3.truth_off);
    let follows: Vec<Ned> = h3
        .truth_off
        .iter()
        .zip(&h3.error)
        .map(|(t, e)| *t + *e)
        .collect();
    let (follow_h, _) = rms(&follows);
    let (rep_h, _) = rms(&h3.reported_off);
    let (gps_h, _) = rms(&h3.gps_minus_truth_and_error);
    eprintln!(
        "3D, 600 s: receiver error RMS {err_h:.2} m h / {err_v:.2} m v; truth off the \
         setpoint {truth_h:.2} m, truth + error {follow_h:.3} m; reported off \
         {rep_h:.3} m; GPS_RAW_INT - truth - error {gps_h:.3} m"
    );
    assert!(err_h >= 0.5 && err_v >= 0.5, "3D error {err_h} {err_v}");
    assert!(truth_h >= 0.5, "the truth wanders by the error: {truth_h}");
    assert!(
        follow_h < 0.2 * err_h,
        "truth = setpoint - error (EKF lag): {follow_h}"
    );
    // The estimate moves with the error's short-term changes (about 0.1 m/s in 3D)
    // and the controller follows it a little behind.
    assert!(
        rep_h < 0.15,
        "the reported position stays on the setpoint: {rep_h}"
    );
    assert!(
        gps_h < 0.15,
        "GPS_RAW_INT = truth + error + white noise: {gps_h}"
    );
    // Corrections: fixed after 20 s; 40 s later, two minutes of centimetres.
    let mut caster = Caster::at(PX4_SITL_HOME);
    let hx = hover(&mut v, hold, 180.0, 60.0, Some(&mut caster));
    assert_eq!(v.truth().gnss.fix_type, 6);
    let (err_h, err_v) = rms(&hx.error);
    let (truth_h, truth_v) = rms(&hx.truth_off);
    let (gps_h, _) = rms(&hx.gps_minus_truth_and_error);
    eprintln!(
        "RTK fixed, 120 s: receiver error RMS {err_h:.4} m h / {err_v:.4} m v; truth off \
         the setpoint {truth_h:.4} m h / {truth_v:.4} m v; GPS_RAW_INT - truth - error \
         {gps_h:.4} m"
    );
    assert!(
        err_h <= 0.03 && err_v <= 0.04,
        "fixed error {err_h} {err_v}"
    );
    assert!(
        truth_h <= 0.05 && truth_v <= 0.06,
        "truth {truth_h} {truth_v}"
    );
    assert!(gps_h <= 0.02, "GPS_RAW_INT in fixed: {gps_h}");
}

#[test]
fn without_the_wander_corrections_change_no_trajectory() {
    // Estimator noise, gusts and GPS noise draw from the vehicle's generator: the RTK
    // path must draw nothing from it and move nothing.
    let flight = |corrections: bool| {
        let mut v = vehicle(|cfg| {
            cfg.seed = 11;
            cfg.estimator_noise = true;
            cfg.gps_noise_m = 0.5;
            cfg.wind = WindConfig::from_direction(4.0, 200.0, 1.0);
            cfg.telemetry = TelemetryProfile::Swarm;
        });
        let mut caster = Caster::at(PX4_SITL_HOME);
        assert!(v.take_off_offboard(10.0, 12.0), "did not take off");
        let hold = Ned::new(5.0, -3.0, -12.0);
        let sp = client::setpoint(client::POSITION_YAW, hold, Ned::ZERO, Ned::ZERO, 0.0);
        let mut trace = Vec::new();
        for k in 0..2500u32 {
            if k.is_multiple_of(50) {
                v.send(&client::gcs_heartbeat());
                if corrections {
                    let epoch = caster.epoch();
                    send_all(&mut v, &epoch);
                }
            }
            v.send(&sp);
            let msgs = v.step();
            let t = v.truth();
            let reported: Vec<[i64; 3]> = msgs
                .into_iter()
                .filter_map(|(_, m)| match m {
                    MavMessage::LOCAL_POSITION_NED(p) => {
                        Some([p.x, p.y, p.z].map(|c| c.to_bits().into()))
                    }
                    MavMessage::GPS_RAW_INT(g) => Some([g.lat, g.lon, g.alt].map(i64::from)),
                    _ => None,
                })
                .collect();
            trace.push((t.local_ned_m, t.velocity_ned_m_s, reported));
        }
        (trace, v.truth().gnss)
    };
    let (plain, plain_gnss) = flight(false);
    let (rtk, rtk_gnss) = flight(true);
    assert_eq!((plain_gnss.fix_type, rtk_gnss.fix_type), (3, 6));
    assert_eq!(rtk_gnss.error_ned_m, [0.0; 3]);
    assert!(plain == rtk, "the same flight, position for position");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrections_over_udp_reach_rtk_fixed() {
    let (sim, mut clients) = start(1, |cfg| {
        cfg.rtk = RtkTiming {
            rtk_float_after_s: 0.5,
            rtk_fixed_after_s: 1.0,
            ..RtkTiming::default()
        };
    })
    .await;
    let c = &mut clients[0];
    let mut caster = Caster::at(PX4_SITL_HOME);
    let deadline = std::time::Instant::now() + Duration::from_secs(15);
    let fixed = loop {
        for m in caster.epoch() {
            c.send(&m).await;
        }
        let fix = c
            .wait_for(Duration::from_millis(200), |f| match &f.msg {
                MavMessage::GPS_RAW_INT(g) if g.fix_type == GpsFixType::GPS_FIX_TYPE_RTK_FIXED => {
                    Some(g.h_acc)
                }
                _ => None,
            })
            .await;
        if fix.is_some() || std::time::Instant::now() > deadline {
            break fix;
        }
    };
    assert_eq!(fixed, Some(17), "GPS_RAW_INT reports RTK fixed, 17 mm");
    // The last epoch may still be on its way: wait until all of it reached the receiver.
    let sent_bytes = u64::from(caster.epochs) * (25 + 446);
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    let stats = loop {
        let s = sim.stats().remove(0);
        if s.rtcm.bytes_to_receiver == sent_bytes || std::time::Instant::now() > deadline {
            break s;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    };
    eprintln!("over UDP, {} epochs: {:?}", caster.epochs, stats.rtcm);
    assert_eq!(stats.truth.gnss.fix_type, 6);
    assert!(stats.truth.gnss.corrections_age_s.is_some_and(|a| a < 1.0));
    let r = stats.rtcm;
    let epochs = u64::from(caster.epochs);
    assert_eq!(r.gps_rtcm_data, epochs * 4);
    assert_eq!(r.bytes_to_receiver, sent_bytes);
    assert_eq!(
        (r.observation_frames, r.base_position_frames),
        (epochs, epochs)
    );
    assert_eq!(
        (r.crc_failures, r.garbage_bytes, r.inject_queue_overruns),
        (0, 0, 0)
    );
    sim.shutdown().await;
}
