//! What the coordinator reports about the process: health (`GET /api/v1/health`), the
//! metrics it reads from the endpoints, the setpoint streams and the load before each
//! render (`GET /metrics`), and the endpoints' counters (`GET /api/v1/links`).

use super::CoordinatorState;
use super::messages::{EndpointStats, Health};
use crate::metrics::Metrics;

impl CoordinatorState {
    /// `GET /api/v1/health`: vehicles, uptime, origin, load.
    pub(super) fn health(&self) -> Health {
        let connected = self
            .vehicles
            .values()
            .filter(|v| v.state().is_connected())
            .count();
        self.metrics.vehicles_connected.set(connected as i64);
        Health {
            status: "ok",
            vehicles: self.vehicles.len(),
            connected,
            uptime_s: self.started.elapsed().as_secs_f64(),
            swarm_origin: self.context.frame().map(|f| f.origin),
            fault_injection: self.context.config.fault_injection,
            coordinator_role: None,
            load: self.load_status(),
        }
    }

    /// The process's load.
    pub(super) fn load_status(&self) -> crate::load::LoadStatus {
        self.supervision.load.status()
    }

    /// `GET /metrics`: the gauges read from the endpoints, streams and load, rendered.
    pub(super) fn render_metrics(&self) -> String {
        self.metrics.set_load(&self.load_status());
        for (e, _) in &self.endpoints {
            self.metrics
                .mavlink_malformed
                .get_or_create(&Metrics::label("connection", &e.address().to_string()))
                .set(e.decode_counts().errors() as i64);
            if let Some(s) = e.signing_counts() {
                self.metrics
                    .mavlink_signing_dropped
                    .get_or_create(&Metrics::label("connection", &e.address().to_string()))
                    .set(s.dropped() as i64);
            }
        }
        if let Some(g) = &self.gcs {
            let c = g.counts();
            let conn = g.address().to_string();
            for (way, n) in [
                ("to_gcs", c.to_gcs),
                ("from_gcs", c.from_gcs),
                ("setpoints_dropped", c.setpoints_dropped),
                ("no_route", c.no_route),
                ("to_gcs_dropped", c.to_gcs_dropped),
            ] {
                self.metrics
                    .gcs_forward_frames
                    .get_or_create(&vec![
                        ("connection".to_string(), conn.clone()),
                        ("kind".to_string(), way.to_string()),
                    ])
                    .set(n as i64);
            }
        }
        for (id, v) in &self.vehicles {
            if let Some(local) = &v.local {
                let counts = local.shared.link.stream().counts();
                let label = Metrics::label("vehicle", id);
                self.metrics
                    .setpoints_sent
                    .get_or_create(&label)
                    .set(counts.sent as i64);
                self.metrics
                    .setpoint_max_gap_ms
                    .get_or_create(&label)
                    .set(counts.max_gap_ms);
            }
        }
        self.metrics
            .payload_threads_abandoned
            .set(i64::try_from(crate::payload::abandoned_driver_threads()).unwrap_or(i64::MAX));
        self.metrics.render()
    }

    /// `GET /api/v1/links`: every endpoint's counters, and the ground-station forwarder's.
    pub(super) fn link_stats(&self) -> Vec<EndpointStats> {
        self.endpoints
            .iter()
            .map(|(e, _)| EndpointStats {
                connection: e.address().to_string(),
                local_addr: e.local_addr().map(|a| a.to_string()),
                decode: e.decode_counts(),
                send: e.send_counts(),
                signing: e.signing_counts(),
                gcs_forward: None,
            })
            .chain(self.gcs.iter().map(|g| EndpointStats {
                connection: g.address().to_string(),
                local_addr: Some(g.local_addr().to_string()),
                decode: g.decode_counts(),
                send: Default::default(),
                signing: None,
                gcs_forward: Some(g.counts()),
            }))
            .collect()
    }
}
