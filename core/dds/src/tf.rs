//! The swarm as a TF tree, for RViz and every tf2 user: this process's vehicles as
//! frames on `/tf`, and the swarm frame's anchor on `/tf_static` (both
//! `tf2_msgs/TFMessage`, with the QoS of tf2's own broadcasters: [`crate::topics`]).
//!
//! Frames, per REP 105 and REP 103:
//!
//! - `skein_swarm` ([`crate::FRAME_ID`]): ENU (x east, y north, z up), metres, about the
//!   swarm origin (`[swarm] origin`, else the first vehicle's home; `GET /api/v1/health`
//!   names it as `swarm_origin`); the frame of every pose on skein's topics;
//! - `<vehicle>/base_link` (`uav_1/base_link`, the vehicle id as a ROS name): the
//!   vehicle's body, FLU, level at the vehicle's heading; on `/tf` at the publish rate,
//!   parent `skein_swarm`, from the same telemetry as `/skein/<vehicle>/pose`;
//! - the anchor, once the swarm frame has its origin and this process has a vehicle to
//!   show: `earth → skein_swarm` (REP 105's `earth` is ECEF, WGS84: the translation is
//!   the origin's ECEF position, the rotation turns ECEF into the local ENU axes), or,
//!   when the user names a parent frame ([`TfConfig::parent_frame`], e.g. `map`), that
//!   frame `→ skein_swarm` as the identity: the user's map frame is declared to be the
//!   swarm frame. One parent only, so that the tree stays a tree.
//!
//! A vehicle another process publishes (a coordinator's remote vehicle) is skipped: its
//! agent publishes its frame, in the agent's swarm frame. Processes whose swarm frames
//! differ (each anchors at its own first vehicle's home unless `[swarm] origin` is given)
//! would publish two different `skein_swarm`s: give every process of a distributed swarm
//! the same `[swarm] origin`.

use crate::carrier::{Carrier, TopicWriter};
use crate::convert::{enu_orientation, enu_point, header};
use crate::counters::DdsCounters;
use crate::error::DdsError;
use crate::msgs::{Quaternion, TfMessage, Transform, TransformStamped, Vector3};
use crate::reframe::FrameSource;
use crate::topics;
use ros2_client::builtin_interfaces::Time;
use skein_model::geo::GeoPoint;
use skein_model::vehicle::VehicleSnapshot;
use std::f64::consts::FRAC_PI_2;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

/// REP 105's earth-centred, earth-fixed frame.
pub const EARTH_FRAME: &str = "earth";

/// What the TF role needs from this process: its swarm frame ([`FrameSource`]) and its
/// vehicles.
pub trait TfContext: FrameSource {
    /// Every vehicle, sorted by id (`None`: no answer).
    fn vehicles(&self) -> impl Future<Output = Option<Vec<VehicleSnapshot>>> + Send;

    /// Whether publishing round `round` goes ahead: every round, unless the process is
    /// short of CPU and sheds optional work.
    fn keep_round(&self, _round: u64) -> impl Future<Output = bool> + Send {
        async { true }
    }
}

/// The TF role's settings (`[dds]` in the config).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TfConfig {
    /// `/tf` publications per second (the pose rate), 0.1 to 100.
    pub publish_rate_hz: f64,
    /// The parent of `skein_swarm` on `/tf_static` (`--dds-tf-parent`, `[dds]
    /// tf_parent_frame`): `None` for `earth` (ECEF, the origin's true place), or a frame
    /// of the user's (`map`) that the swarm frame is the identity of.
    pub parent_frame: Option<String>,
}

/// Whether `frame` can name a TF frame: not empty, no leading `/` (tf2 refuses one),
/// letters, digits, `_` and `/` only, and not `skein_swarm` itself.
///
/// # Errors
/// Which rule it breaks.
pub fn check_frame_id(frame: &str) -> Result<(), String> {
    if frame.is_empty() {
        return Err("a frame id cannot be empty".into());
    }
    if frame.starts_with('/') {
        return Err(format!("`{frame}`: tf2 frame ids do not start with `/`"));
    }
    if let Some(c) = frame
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '/'))
    {
        return Err(format!("`{frame}`: `{c}` is not allowed in a frame id"));
    }
    if frame == crate::FRAME_ID {
        return Err(format!("`{frame}` is the swarm frame itself"));
    }
    Ok(())
}

/// The TF role: its two writers (see the module docs).
pub struct Tf {
    config: TfConfig,
    /// True for a vehicle another process publishes.
    elsewhere: Box<dyn Fn(&str) -> bool + Send + Sync>,
    tf: TopicWriter<TfMessage>,
    tf_static: TopicWriter<TfMessage>,
}

impl Tf {
    /// Opens `/tf` and `/tf_static` on `carrier`, counting in `counters`; skips the
    /// vehicles for which `elsewhere` is true.
    ///
    /// # Errors
    /// A topic or writer could not be created.
    pub fn open(
        carrier: &impl Carrier,
        counters: &Arc<DdsCounters>,
        config: TfConfig,
        elsewhere: Box<dyn Fn(&str) -> bool + Send + Sync>,
    ) -> Result<Self, DdsError> {
        Ok(Tf {
            tf: TopicWriter::open(carrier, &topics::tf(), counters)?,
            tf_static: TopicWriter::open(carrier, &topics::tf_static(), counters)?,
            config,
            elsewhere,
        })
    }

    /// The frames of this process's vehicles with a position, stamped `stamp`.
    pub fn vehicle_frames(&self, vehicles: &[VehicleSnapshot], stamp: Time) -> TfMessage {
        TfMessage {
            transforms: vehicles
                .iter()
                .filter(|v| !(self.elsewhere)(&v.id))
                .filter_map(|v| vehicle_frame(v, stamp))
                .collect(),
        }
    }

    /// The anchor of the swarm frame at `origin` (see the module docs), stamped `stamp`.
    pub fn anchor(&self, origin: GeoPoint, stamp: Time) -> TfMessage {
        let transform = match &self.config.parent_frame {
            Some(parent) => TransformStamped {
                header: header(stamp, parent),
                child_frame_id: crate::FRAME_ID.into(),
                transform: Transform {
                    translation: Vector3::default(),
                    rotation: IDENTITY,
                },
            },
            None => earth_to_swarm(origin, stamp),
        };
        TfMessage {
            transforms: vec![transform],
        }
    }
}

/// The identity rotation.
const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

/// The TF frame of vehicle `id`: `<ros name>/base_link` (`uav_1/base_link`).
pub fn vehicle_frame_id(id: &str) -> String {
    format!("{}/base_link", topics::ros_name(id))
}

/// `skein_swarm → <vehicle>/base_link`: `None` before the vehicle's position is known.
pub fn vehicle_frame(v: &VehicleSnapshot, stamp: Time) -> Option<TransformStamped> {
    let p = enu_point(v.position?.ned());
    Some(TransformStamped {
        header: header(stamp, crate::FRAME_ID),
        child_frame_id: vehicle_frame_id(&v.id),
        transform: Transform {
            translation: Vector3 {
                x: p.x,
                y: p.y,
                z: p.z,
            },
            rotation: enu_orientation(v.heading_deg),
        },
    })
}

/// `earth → skein_swarm` for a swarm frame about `origin`: the origin's ECEF position,
/// and the rotation whose columns are the local east, north and up axes in ECEF (a turn
/// of `longitude + π/2` about ECEF z after one of `π/2 − latitude` about x).
pub fn earth_to_swarm(origin: GeoPoint, stamp: Time) -> TransformStamped {
    let [x, y, z] = origin.to_ecef();
    let (yaw, tilt) = (
        origin.lon_deg.to_radians() + FRAC_PI_2,
        FRAC_PI_2 - origin.lat_deg.to_radians(),
    );
    let (sz, cz) = (yaw / 2.0).sin_cos();
    let (sx, cx) = (tilt / 2.0).sin_cos();
    TransformStamped {
        header: header(stamp, EARTH_FRAME),
        child_frame_id: crate::FRAME_ID.into(),
        transform: Transform {
            translation: Vector3 { x, y, z },
            rotation: Quaternion {
                x: cz * sx,
                y: sz * sx,
                z: cx * sz,
                w: cz * cx,
            },
        },
    }
}

/// Publishes `/tf` at the rate, and `/tf_static` whenever the anchor is new, until the
/// task is aborted.
pub async fn run<X: TfContext>(tf: Arc<Tf>, ctx: Arc<X>) {
    let period = Duration::from_secs_f64(1.0 / tf.config.publish_rate_hz.clamp(0.1, 100.0));
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut n: u64 = 0;
    let mut anchored: Option<GeoPoint> = None;
    loop {
        tick.tick().await;
        n += 1;
        if !ctx.keep_round(n).await {
            continue;
        }
        let Some(list) = ctx.vehicles().await else {
            continue;
        };
        let frames = tf.vehicle_frames(&list, Time::now());
        if frames.transforms.is_empty() {
            continue;
        }
        let origin = match ctx.swarm_frame().await.and_then(|f| f.frame()) {
            Some(frame) => frame.origin,
            None => continue,
        };
        if anchored != Some(origin) && tf.tf_static.publish(tf.anchor(origin, Time::now())).is_ok()
        {
            anchored = Some(origin);
        }
        let _ = tf.tf.publish(frames);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `v` turned by unit quaternion `q`.
    fn rotate(q: &Quaternion, v: [f64; 3]) -> [f64; 3] {
        let (w, x, y, z) = (q.w, q.x, q.y, q.z);
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
    }

    #[test]
    fn the_anchor_turns_enu_into_ecef_at_the_origin() {
        let origin = GeoPoint::new(47.397_742, 8.545_594, 488.0);
        let t = earth_to_swarm(origin, Time::ZERO);
        assert_eq!(t.header.frame_id, "earth");
        assert_eq!(t.child_frame_id, "skein_swarm");
        let q = t.transform.rotation;
        let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
        assert!((norm - 1.0).abs() < 1e-12);
        // A point 100 m east and 50 m up of the origin, through the transform, is the
        // ECEF position of the same point computed geodetically.
        let frame = skein_model::geo::NedFrame::new(origin);
        let geo = frame.to_geo(skein_model::geo::Ned::new(0.0, 100.0, -50.0));
        let want = geo.to_ecef();
        let r = rotate(&q, [100.0, 0.0, 50.0]);
        let tr = t.transform.translation;
        let got = [r[0] + tr.x, r[1] + tr.y, r[2] + tr.z];
        for i in 0..3 {
            assert!((got[i] - want[i]).abs() < 1e-3, "{got:?} vs {want:?}");
        }
        // Up is along the ellipsoid normal: at the origin's latitude.
        let up = rotate(&q, [0.0, 0.0, 1.0]);
        let lat = up[2].asin().to_degrees();
        assert!((lat - origin.lat_deg).abs() < 1e-9, "{lat}");
    }

    /// A process with fixed vehicles in a frame about `origin`.
    struct Fixed {
        frame: Arc<crate::reframe::AnchoredFrame>,
        vehicles: Vec<VehicleSnapshot>,
    }

    impl FrameSource for Fixed {
        async fn swarm_frame(&self) -> Option<Arc<dyn crate::reframe::SwarmFrame>> {
            Some(self.frame.clone())
        }
    }

    impl TfContext for Fixed {
        async fn vehicles(&self) -> Option<Vec<VehicleSnapshot>> {
            Some(self.vehicles.clone())
        }
    }

    /// Runs the role for `rounds` publish periods on a bus with vehicles `uav-1` (10 m
    /// north, 5 m east, 3 m up, heading east), `uav-2` (another process's) and `uav-3`
    /// (no position yet); the samples written, the last on `/tf` and, read afterwards,
    /// what `/tf_static` holds.
    async fn publish(parent: Option<&str>, rounds: u32) -> (u64, TfMessage, Vec<TfMessage>) {
        use crate::carrier::Carrier;
        use crate::carrier::memory::MemoryBus;
        use skein_model::geo::{Ned, NedFrame};
        let origin = GeoPoint::new(47.397_742, 8.545_594, 488.0);
        let frame = NedFrame::new(origin);
        let mut uav1 = VehicleSnapshot::hovering_at("uav-1", 1, &frame, Ned::new(10.0, 5.0, -3.0));
        uav1.heading_deg = 90.0;
        let uav2 = VehicleSnapshot::hovering_at("uav-2", 2, &frame, Ned::new(0.0, 0.0, -3.0));
        let mut uav3 = VehicleSnapshot::hovering_at("uav-3", 3, &frame, Ned::ZERO);
        uav3.position = None;
        let bus = MemoryBus::new();
        let tf_reader = bus.reader::<TfMessage>(&topics::tf()).unwrap();
        let config = TfConfig {
            publish_rate_hz: 10.0,
            parent_frame: parent.map(str::to_string),
        };
        let counters = Arc::new(DdsCounters::default());
        let role = Arc::new(
            Tf::open(
                bus.as_ref(),
                &counters,
                config,
                Box::new(|id| id == "uav-2"),
            )
            .unwrap(),
        );
        let ctx = Arc::new(Fixed {
            frame: Arc::new(crate::reframe::AnchoredFrame::new(Some(origin))),
            vehicles: vec![uav1, uav2, uav3],
        });
        let task = tokio::spawn(run(role, ctx));
        tokio::time::sleep(Duration::from_millis(100) * rounds - Duration::from_millis(50)).await;
        task.abort();
        // Keep-last 1: the reader holds the last round's.
        let last = tf_reader.try_take().unwrap().expect("a /tf sample");
        // A reader that comes late (RViz started after skein) still gets the anchor.
        let static_reader = bus.reader::<TfMessage>(&topics::tf_static()).unwrap();
        let mut tf_static = vec![];
        while let Ok(Some(m)) = static_reader.try_take() {
            tf_static.push(m);
        }
        let published = counters
            .published
            .load(std::sync::atomic::Ordering::Relaxed);
        (published, last, tf_static)
    }

    #[tokio::test(start_paused = true)]
    async fn each_round_carries_this_process_s_vehicles_and_the_anchor_comes_once() {
        let (published, last, tf_static) = publish(None, 5).await;
        // Five rounds on /tf, the anchor once.
        assert_eq!(published, 6);
        assert_eq!(last.transforms.len(), 1, "{last:?}");
        let t = &last.transforms[0];
        assert_eq!(t.header.frame_id, "skein_swarm");
        assert_eq!(t.child_frame_id, "uav_1/base_link");
        let p = t.transform.translation;
        assert!(
            (p.x - 5.0).abs() < 1e-6 && (p.y - 10.0).abs() < 1e-6,
            "{p:?}"
        );
        assert!((p.z - 3.0).abs() < 1e-6, "{p:?}");
        // Heading east is an ENU yaw of 0.
        assert!(t.transform.rotation.z.abs() < 1e-12);
        assert_eq!(tf_static.len(), 1, "{tf_static:?}");
        assert_eq!(tf_static[0].transforms[0].header.frame_id, "earth");
    }

    #[tokio::test(start_paused = true)]
    async fn a_named_parent_is_the_identity_of_the_swarm_frame() {
        let (_, _, tf_static) = publish(Some("map"), 2).await;
        let t = &tf_static[0].transforms[0];
        assert_eq!(
            (t.header.frame_id.as_str(), t.child_frame_id.as_str()),
            ("map", "skein_swarm")
        );
        assert_eq!(t.transform.translation, Vector3::default());
        assert_eq!(t.transform.rotation, IDENTITY);
    }

    #[test]
    fn frame_ids_follow_tf2s_rules() {
        assert_eq!(vehicle_frame_id("uav-1"), "uav_1/base_link");
        assert!(check_frame_id("map").is_ok());
        assert!(check_frame_id("site_a/map").is_ok());
        for bad in ["", "/map", "my map", "skein_swarm"] {
            assert!(check_frame_id(bad).is_err(), "{bad}");
        }
    }
}
