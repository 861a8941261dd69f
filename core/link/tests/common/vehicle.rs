//! A vehicle of a test: its `VehicleLink`, its `Px4Link` actor, and the events the link
//! reported, recorded.

use super::eventually;
use ractor::{Actor, ActorRef};
use skein_link::endpoint::Discovery;
use skein_link::{
    Endpoint, LinkCommand, LinkError, LinkEvent, LinkSetup, Px4Link, Px4LinkArgs, Px4LinkMsg,
    VehicleLink,
};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A linked vehicle (see the module docs).
pub struct Vehicle {
    /// Its link's shared state.
    pub link: Arc<VehicleLink>,
    /// Its link actor.
    pub actor: ActorRef<Px4LinkMsg>,
    /// Every event the link reported, in order.
    pub events: Arc<Mutex<Vec<LinkEvent>>>,
}

impl Vehicle {
    /// Some event so far satisfies `pred`.
    pub fn saw(&self, pred: impl Fn(&LinkEvent) -> bool) -> bool {
        self.events.lock().unwrap().iter().any(pred)
    }

    /// Waits (10 s at most) until the link knows the vehicle's home: its EKF has a
    /// global position.
    pub async fn home_known(&self) {
        eventually("home known", Duration::from_secs(10), || {
            self.link.with_telemetry(|t| t.home.is_some()).then_some(())
        })
        .await;
    }

    /// Runs `cmd` through the link and waits for its outcome.
    pub async fn command(&self, cmd: LinkCommand) -> Result<(), LinkError> {
        ractor::call_t!(self.actor, Px4LinkMsg::Command, 15_000, cmd).expect("link actor answers")
    }
}

/// Links the vehicle `d` discovered on `endpoint`, with `setup`.
pub async fn attach(endpoint: &Arc<Endpoint>, d: &Discovery, setup: LinkSetup) -> Vehicle {
    let link = VehicleLink::new(endpoint.clone(), d.sysid, d.compid, 20.0, setup);
    let events = Arc::new(Mutex::new(Vec::new()));
    let sink = events.clone();
    let (actor, _) = Actor::spawn(
        None,
        Px4Link,
        Px4LinkArgs {
            link: link.clone(),
            events: Arc::new(move |e| sink.lock().unwrap().push(e)),
            components: None,
        },
    )
    .await
    .unwrap();
    Vehicle {
        link,
        actor,
        events,
    }
}
