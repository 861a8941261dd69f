//! The DDS carrier: a ROS 2 node (`/skein/<node name>`) on a RustDDS participant,
//! through ros2-client; its writers are `Publisher`s and its readers `Subscription`s.
//! Dropping it leaves the domain.

use super::{Carrier, CarrierError, NextSample, Reader, Sample, Writer, WriterIdentity};
use crate::error::{DdsError, err};
use crate::security::DdsSecurity;
use crate::topics::{self, TopicSpec};
use ros2_client::dds::rustdds::{DomainParticipantBuilder, Topic};
use ros2_client::{
    Context, MessageInfo, Name, Node, NodeName, NodeOptions, Publisher, Subscription,
};
use std::collections::BTreeMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex, PoisonError};

/// A ROS 2 node on the DDS domain (see the module docs).
pub struct Ros2Carrier {
    // Kept alive for the node's life (dropping it leaves the domain).
    _context: Context,
    node: Mutex<Node>,
    /// Topics made so far, by ROS name: one DDS topic per name, however many readers and
    /// writers it has.
    topics: Mutex<BTreeMap<String, Topic>>,
    /// Joined with DDS Security: samples name their writer's identity.
    secured: bool,
}

impl Ros2Carrier {
    /// Joins DDS domain `domain_id` (0–232) as node `/skein/<node_name>`; with
    /// `networks`, DDS uses only the interfaces of those local addresses (RustDDS
    /// `with_only_networks`), else every interface. With `security`, the participant
    /// presents that enclave and speaks only DDS Security (RustDDS's builtin plugins):
    /// peers without a certificate of the keystore's CA are refused, and every reader
    /// and writer is checked against the enclave's permissions.
    ///
    /// # Errors
    /// The participant (sockets, or the enclave's certificate, key, governance or
    /// permissions), context or node (name) could not be created.
    pub fn join(
        domain_id: u16,
        networks: &[IpAddr],
        node_name: &str,
        security: Option<&DdsSecurity>,
    ) -> Result<Self, DdsError> {
        let mut participant = DomainParticipantBuilder::new(domain_id);
        if !networks.is_empty() {
            participant = participant.with_only_networks(networks.iter().copied());
        }
        if let Some(s) = security {
            crate::security::refusals::install();
            participant = participant.builtin_security(s.config_files());
        }
        let participant = participant.build().map_err(|e| match security {
            Some(s) => DdsError(format!(
                "DDS participant with enclave {} ({}): {e:?}",
                s.enclave,
                s.dir.display()
            )),
            None => DdsError(format!("DDS participant: {e:?}")),
        })?;
        let context =
            Context::from_domain_participant(participant).map_err(err("ROS 2 context"))?;
        let node = context
            .new_node(
                NodeName::new(topics::NAMESPACE, node_name).map_err(err("node name"))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(err("ROS 2 node"))?;
        Ok(Ros2Carrier {
            _context: context,
            node: Mutex::new(node),
            topics: Mutex::new(BTreeMap::new()),
            secured: security.is_some(),
        })
    }

    /// The node, and the DDS topic of `spec` carrying `M` (made the first time).
    fn topic<M: Sample>(
        &self,
        spec: &TopicSpec,
    ) -> Result<(Topic, std::sync::MutexGuard<'_, Node>), DdsError> {
        let node = self.node.lock().unwrap_or_else(PoisonError::into_inner);
        let mut topics = self.topics.lock().unwrap_or_else(PoisonError::into_inner);
        let key = spec.to_string();
        if let Some(t) = topics.get(&key) {
            return Ok((t.clone(), node));
        }
        let name = Name::new(&spec.namespace, spec.name).map_err(err(spec.name))?;
        let t = node
            .create_topic(&name, M::type_name(), &spec.qos)
            .map_err(err(spec.name))?;
        topics.insert(key, t.clone());
        Ok((t, node))
    }
}

impl Carrier for Ros2Carrier {
    fn writer<M: Sample>(&self, spec: &TopicSpec) -> Result<Arc<dyn Writer<M>>, DdsError> {
        let (topic, mut node) = self.topic::<M>(spec)?;
        let p: Publisher<M> = node
            .create_publisher(&topic, None)
            .map_err(err("publisher"))?;
        Ok(Arc::new(p))
    }

    fn reader<M: Sample>(&self, spec: &TopicSpec) -> Result<Arc<dyn Reader<M>>, DdsError> {
        let (topic, mut node) = self.topic::<M>(spec)?;
        let subscription: Subscription<M> = node
            .create_subscription(&topic, None)
            .map_err(err("subscription"))?;
        Ok(Arc::new(Ros2Reader {
            subscription,
            secured: self.secured,
        }))
    }
}

/// A subscription, and whether its participant is secured (then its samples' writer GUIDs
/// are authenticated: [`WriterIdentity`]).
struct Ros2Reader<M: Sample> {
    subscription: Subscription<M>,
    secured: bool,
}

impl<M: Sample> Ros2Reader<M> {
    fn identity(&self, info: &MessageInfo) -> Option<WriterIdentity> {
        self.secured.then(|| {
            let gid = info.publisher_gid().to_bytes16();
            let mut id = [0; 6];
            id.copy_from_slice(&gid[..6]);
            WriterIdentity(id)
        })
    }
}

impl<M: Sample> Writer<M> for Publisher<M> {
    fn write(&self, sample: M) -> Result<(), CarrierError> {
        self.publish(sample)
            .map_err(|e| CarrierError(e.to_string()))
    }
}

impl<M: Sample> Reader<M> for Ros2Reader<M> {
    fn try_take(&self) -> Result<Option<M>, CarrierError> {
        self.subscription
            .take()
            .map(|s| s.map(|(m, _)| m))
            .map_err(|e| CarrierError(format!("{e:?}")))
    }

    fn take_next(&self) -> NextSample<'_, M> {
        Box::pin(async move {
            self.subscription
                .async_take()
                .await
                .map(|(m, info)| (m, self.identity(&info)))
                .map_err(|e| CarrierError(format!("{e:?}")))
        })
    }
}
