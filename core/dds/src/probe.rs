//! A listener of skein's topics, for `skein bench dds`: it subscribes to
//! `/skein/<vehicle>/pose` of the given vehicles as any ROS 2 node would, or to the
//! coordinators' slot targets on `/skein/swarm/target` as an agent does, and records, for
//! each sample, the time from its header stamp (set by the publisher just before it
//! writes) to its arrival here. Both clocks are the same host's wall clock when the probe
//! runs beside skein.

use crate::carrier::Carrier;
use crate::carrier::ros2::Ros2Carrier;
use crate::msgs::{PoseStamped, SwarmMessage};
use crate::security::DdsSecurity;
use crate::topics;
use crate::{DdsError, FRAME_ID};
use ros2_client::builtin_interfaces::Time;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, PoisonError};
use tokio::task::JoinSet;

/// One received pose or target: the vehicle and its latency, seconds.
pub type Arrival = (String, f64);

/// Subscriptions to the poses of some vehicles, or to the targets (see the module docs). Dropping it leaves
/// the domain.
pub struct PoseProbe {
    // Kept for the probe's life (dropping it leaves the domain).
    _carrier: Ros2Carrier,
    arrivals: Arc<Mutex<Vec<Arrival>>>,
    tasks: JoinSet<()>,
}

impl PoseProbe {
    /// Joins `domain_id` (on `networks` only, when not empty) and subscribes to the poses
    /// of `vehicles` (ids as the API names them), and with `targets` to the slot targets
    /// of every vehicle, with the QoS they are published with; presents `security`'s
    /// enclave when given (a viewer's reads both).
    ///
    /// # Errors
    /// The participant, node or a subscription could not be created.
    pub fn start(
        domain_id: u16,
        networks: &[IpAddr],
        vehicles: &[String],
        targets: bool,
        security: Option<&DdsSecurity>,
    ) -> Result<Self, DdsError> {
        let carrier = Ros2Carrier::join(
            domain_id,
            networks,
            &format!("skein_probe_{}", std::process::id()),
            security,
        )?;
        let arrivals: Arc<Mutex<Vec<Arrival>>> = Arc::new(Mutex::new(Vec::new()));
        let mut tasks = JoinSet::new();
        if targets {
            let sub = carrier.reader::<SwarmMessage>(&topics::swarm_target())?;
            let arrivals = arrivals.clone();
            tasks.spawn(async move {
                while let Ok((m, _)) = sub.take_next().await {
                    let latency_s =
                        (Time::now().to_nanos() - m.header.stamp.to_nanos()) as f64 * 1e-9;
                    arrivals
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .push((m.vehicle_id, latency_s));
                }
            });
        }
        for id in vehicles {
            let sub = carrier.reader::<PoseStamped>(&topics::pose(id))?;
            let (id, arrivals) = (id.clone(), arrivals.clone());
            tasks.spawn(async move {
                while let Ok((pose, _)) = sub.take_next().await {
                    if pose.header.frame_id != FRAME_ID {
                        continue;
                    }
                    let latency_s =
                        (Time::now().to_nanos() - pose.header.stamp.to_nanos()) as f64 * 1e-9;
                    arrivals
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .push((id.clone(), latency_s));
                }
            });
        }
        Ok(PoseProbe {
            _carrier: carrier,
            arrivals,
            tasks,
        })
    }

    /// The arrivals since the last call (or the start).
    pub fn take(&self) -> Vec<Arrival> {
        std::mem::take(&mut *self.arrivals.lock().unwrap_or_else(PoisonError::into_inner))
    }
}

impl Drop for PoseProbe {
    fn drop(&mut self) {
        self.tasks.abort_all();
    }
}
