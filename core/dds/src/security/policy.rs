//! What DDS Security enforces on skein's domain: the governance (one for the keystore) and
//! the permissions of each role (one per enclave), as the OMG DDS Security 1.1 XML
//! documents (`omg_shared_ca_governance.xsd`, `omg_shared_ca_permissions.xsd`) that
//! SROS 2 writes and RustDDS's builtin access control reads.
//!
//! DDS topic names are the ROS 2 names with `rt` before them (`/skein/swarm/report` is
//! `rt/skein/swarm/report`); `ros_discovery_info` is the ROS 2 graph topic every context
//! reads and writes, `rt/parameter_events` and `rt/rosout` the topics every ROS 2 context opens.
//! Patterns are fnmatch globs (`*` also matches `/`).

use std::fmt::Write as _;

/// A participant's role on the swarm's domain: what its permissions let it write and read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// `skein agent`: writes its vehicles' reports, events, command results, clock
    /// exchanges, per-vehicle ROS 2 topics and its cameras' tracks; reads the leases, targets, commands,
    /// formation mirror and relayed RTK corrections. Cannot write a lease, a target, a
    /// swarm command or corrections.
    Agent,
    /// `skein coordinator` or `skein up --dds`: writes leases, targets, swarm commands,
    /// clock exchanges, the formation and mission mirrors (`/skein/mission`), RTK
    /// corrections (`/skein/rtcm`), tracks and (its own vehicles') per-vehicle topics;
    /// reads every skein topic. Cannot write an agent's report, event or result.
    Coordinator,
    /// A ground-station or ROS 2 tool that only watches: reads every skein topic, writes none.
    Viewer,
}

impl Role {
    /// Every role, as `--role` names them.
    pub const ALL: [Role; 3] = [Role::Agent, Role::Coordinator, Role::Viewer];

    /// The name `--role` takes (`agent`, `coordinator`, `viewer`).
    pub fn name(self) -> &'static str {
        match self {
            Role::Agent => "agent",
            Role::Coordinator => "coordinator",
            Role::Viewer => "viewer",
        }
    }

    /// DDS topic patterns the role may publish on.
    pub fn publishes(self) -> Vec<&'static str> {
        let own: &[&str] = match self {
            Role::Agent => &[
                "rt/skein/tracks",
                "rt/skein/swarm/report",
                "rt/skein/swarm/events",
                "rt/skein/swarm/command_result",
                "rt/skein/swarm/clock",
            ],
            Role::Coordinator => &[
                "rt/skein/coordinator",
                "rt/skein/formation",
                "rt/skein/mission",
                "rt/skein/tracks",
                "rt/skein/swarm/target",
                "rt/skein/swarm/command",
                "rt/skein/swarm/clock",
                "rt/skein/rtcm",
            ],
            Role::Viewer => &[],
        };
        let vehicles: &[&str] = match self {
            Role::Agent | Role::Coordinator => VEHICLE_TOPICS,
            Role::Viewer => &[],
        };
        [own, vehicles, ROS_GRAPH].concat()
    }

    /// DDS topic patterns the role may subscribe to.
    pub fn subscribes(self) -> Vec<&'static str> {
        let own: &[&str] = match self {
            Role::Agent => &[
                "rt/skein/coordinator",
                "rt/skein/formation",
                "rt/skein/rtcm",
                "rt/skein/swarm/*",
                "rt/skein/*/command",
            ],
            Role::Coordinator | Role::Viewer => &["rt/skein/*", "rt/tf*"],
        };
        [own, ROS_GRAPH].concat()
    }
}

/// The topics of the vehicles a process runs (`skein_dds::vehicles`, `skein_dds::tf`).
const VEHICLE_TOPICS: &[&str] = &[
    "rt/skein/*/pose",
    "rt/skein/*/navsat",
    "rt/skein/*/battery",
    "rt/skein/*/state",
    "rt/skein/*/command_result",
    "rt/tf",
    "rt/tf_static",
];

/// The topics every ROS 2 context opens, whatever the role.
const ROS_GRAPH: &[&str] = &["rt/parameter_events", "rt/rosout", "ros_discovery_info"];

impl std::str::FromStr for Role {
    type Err = String;

    /// `agent`, `coordinator` or `viewer`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Role::ALL
            .into_iter()
            .find(|r| r.name() == s)
            .ok_or_else(|| format!("role `{s}`: agent, coordinator or viewer"))
    }
}

impl std::fmt::Display for Role {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// DDS domain ids a keystore's documents cover: every one a ROS 2 domain can be (0–232).
const DOMAINS: &str = "<domains><id_range><min>0</min><max>232</max></id_range></domains>";

/// The keystore's governance document (unsigned): participants without a certificate
/// from the identity CA are refused (`allow_unauthenticated_participants` false), joining
/// needs permissions (`enable_join_access_control`), discovery and liveliness are
/// encrypted, every RTPS message is signed (AES-GMAC: no forged or altered message from
/// outside the swarm), and every topic is access-controlled both ways with each of its
/// submessages encrypted (`metadata_protection_kind` ENCRYPT, AES-GCM: the DATA
/// submessage, and so the sample, with them).
///
/// `data_protection_kind` (a second, payload-only transform inside the encrypted
/// submessage) is NONE: RustDDS 0.15's payload transform fails to decode between two
/// RustDDS participants (every sample dropped with ring's `Unspecified`, measured with
/// both ENCRYPT and SIGN), and the submessage encryption already covers the payload.
pub fn governance_xml() -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      {DOMAINS}
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>SIGN</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>NONE</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"#
    )
}

/// The permissions document (unsigned) of the participant whose identity certificate's
/// subject is `subject` (RFC 4514, `CN=/skein/agent/a2`), granted `role`'s topics from
/// `not_before` to `not_after` (UTC, `YYYY-MM-DDTHH:MM:SS`), everything else denied.
pub fn permissions_xml(subject: &str, role: Role, not_before: &str, not_after: &str) -> String {
    let topics = |patterns: &[&str]| {
        patterns.iter().fold(String::new(), |mut s, p| {
            let _ = write!(s, "<topic>{}</topic>", xml_text(p));
            s
        })
    };
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{grant}">
      <subject_name>{subject}</subject_name>
      <validity>
        <not_before>{not_before}</not_before>
        <not_after>{not_after}</not_after>
      </validity>
      <allow_rule>
        {DOMAINS}
        <publish><topics>{publish}</topics></publish>
        <subscribe><topics>{subscribe}</topics></subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
"#,
        grant = xml_text(&format!("skein {role}")),
        subject = xml_text(subject),
        publish = topics(&role.publishes()),
        subscribe = topics(&role.subscribes()),
    )
}

/// `s` with XML's special characters escaped, for element text and attribute values.
fn xml_text(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_parse_from_their_names_and_nothing_else() {
        for r in Role::ALL {
            assert_eq!(r.name().parse::<Role>(), Ok(r));
        }
        let e = "operator".parse::<Role>().unwrap_err();
        assert!(e.contains("agent, coordinator or viewer"), "{e}");
    }

    #[test]
    fn only_coordinators_write_leases_targets_and_swarm_commands() {
        let writes = |r: Role, topic: &str| r.publishes().contains(&topic);
        for t in [
            "rt/skein/coordinator",
            "rt/skein/swarm/target",
            "rt/skein/swarm/command",
            "rt/skein/mission",
        ] {
            assert!(writes(Role::Coordinator, t), "{t}");
            assert!(!writes(Role::Agent, t), "{t}");
            assert!(!writes(Role::Viewer, t), "{t}");
        }
        assert!(writes(Role::Agent, "rt/skein/swarm/report"));
        assert!(!writes(Role::Coordinator, "rt/skein/swarm/report"));
    }

    #[test]
    fn only_coordinators_write_rtk_corrections_and_agents_read_them() {
        let rtcm = "rt/skein/rtcm";
        assert!(Role::Coordinator.publishes().contains(&rtcm));
        assert!(!Role::Agent.publishes().contains(&rtcm));
        assert!(!Role::Viewer.publishes().contains(&rtcm));
        assert!(Role::Agent.subscribes().contains(&rtcm));
        // Coordinators and viewers read every skein topic.
        for r in [Role::Coordinator, Role::Viewer] {
            assert!(r.subscribes().contains(&"rt/skein/*"), "{r}");
        }
    }

    #[test]
    fn a_subject_with_markup_is_escaped() {
        let x = permissions_xml(
            "CN=a<b>&c",
            Role::Viewer,
            "2026-01-01T00:00:00",
            "2027-01-01T00:00:00",
        );
        assert!(
            x.contains("<subject_name>CN=a&lt;b&gt;&amp;c</subject_name>"),
            "{x}"
        );
    }
}
