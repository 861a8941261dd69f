//! The HTTP API and dashboard of every role: where it listens (`--http`, `[http]
//! listen`), who may use it (`[[http.tokens]]`, refused on a non-loopback address without
//! them unless `--insecure-no-auth`), TLS (`[http] tls_cert`/`tls_key`) and the map
//! tiles (`--map-tiles`, `[map]`), resolved before anything flies; then the API served as
//! a service the coordinator supervises, with what the other parts add to it.

use super::dds::Dds;
use super::options::UpArgs;
use super::plugins::Plugins;
use super::services::add_service;
use crate::config::ConfigFile;
use skein_swarm::Swarm;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;

/// Where the API listens without `--http` or `[http] listen`.
pub(crate) const DEFAULT_HTTP: SocketAddr = SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 8080);

/// Why skein will not listen on `addr`: not loopback, no tokens, and no
/// `--insecure-no-auth`.
pub(crate) fn refuse_unauthenticated(
    addr: SocketAddr,
    tokens: usize,
    insecure: bool,
) -> Result<(), String> {
    if tokens > 0 || insecure || addr.ip().is_loopback() {
        return Ok(());
    }
    Err(format!(
        "refusing to listen on {addr} without authentication: anyone on that network could \
         fly the swarm. Add tokens to the config ([[http.tokens]], made by `skein token create \
         --role operator`), listen on 127.0.0.1, or pass --insecure-no-auth if you really mean it"
    ))
}

/// The API's settings, checked.
pub(super) struct ApiSettings {
    /// The address to listen on (port 0: a free one).
    http: SocketAddr,
    auth: skein_api::auth::Auth,
    tls: Option<Arc<rustls::ServerConfig>>,
    map: skein_api::map::MapTiles,
    /// `[logs] fetch_after_landing`.
    fetch_logs_after_landing: bool,
}

/// The API's socket, bound.
pub(super) struct Listener {
    listener: std::net::TcpListener,
    /// The address it is bound to (the port chosen for port 0).
    pub(super) local: SocketAddr,
}

impl ApiSettings {
    /// The settings of `args` over those of `file`.
    ///
    /// # Errors
    /// A non-loopback address without authentication, a bad token or TLS file, TLS keys
    /// not given together, a map tile set that cannot be read.
    pub(super) fn resolve(args: &UpArgs, file: &ConfigFile) -> Result<ApiSettings, String> {
        let http = args.http.or(file.http.listen).unwrap_or(DEFAULT_HTTP);
        refuse_unauthenticated(http, file.http.tokens.len(), args.insecure_no_auth)?;
        let auth = skein_api::auth::Auth::new(&file.http.tokens)?;
        let tls = match (&file.http.tls_cert, &file.http.tls_key) {
            (Some(cert), Some(key)) => Some(skein_api::tls::server_config(cert, key)?),
            (None, None) => None,
            _ => return Err("[http]: tls_cert and tls_key go together".into()),
        };
        // The map first: a tile set that cannot be read stops skein before anything flies.
        let mut map_config = file.map.clone();
        if let Some(p) = &args.map_tiles {
            map_config.tiles = Some(p.clone());
        }
        let map = skein_api::map::MapTiles::from_config(&map_config)
            .map_err(|e| format!("--map-tiles / [map]: {e}"))?;
        if args.insecure_no_auth && !auth.enabled() && !http.ip().is_loopback() {
            eprintln!(
                "skein: WARNING: --insecure-no-auth: the API on {http} has no authentication"
            );
        }
        Ok(ApiSettings {
            http,
            auth,
            tls,
            map,
            fetch_logs_after_landing: file.logs.fetch_after_landing,
        })
    }

    /// `https` with TLS, else `http`.
    pub(super) fn scheme(&self) -> &'static str {
        if self.tls.is_some() { "https" } else { "http" }
    }

    /// Binds the API's socket.
    ///
    /// # Errors
    /// The address is in use or not this host's.
    pub(super) fn bind(&self) -> Result<Listener, String> {
        let http = self.http;
        let listener =
            std::net::TcpListener::bind(http).map_err(|e| format!("--http {http}: {e}"))?;
        let local = listener.local_addr().map_err(|e| e.to_string())?;
        Ok(Listener { listener, local })
    }

    /// Has the coordinator serve the API on `listener`, with the plugins, the recorder, the
    /// RTK corrections and what the DDS link adds (the election, peer clocks, link
    /// security), and prints the dashboard's address.
    ///
    /// # Errors
    /// The coordinator did not start the service.
    pub(super) async fn serve(
        self,
        listener: Listener,
        plugins: Plugins,
        recorder: &Arc<skein_record::Recorder>,
        rtk: Arc<skein_rtk::RtkService>,
        dds: Option<&Dds>,
        swarm: &Swarm,
    ) -> Result<(), String> {
        let scheme = self.scheme();
        let mut state = skein_api::ApiState::new(
            swarm.coordinator.clone(),
            swarm.reads.clone(),
            swarm.events.clone(),
        )
        .with_plugins(plugins.manager, plugins.refused)
        .with_map(self.map)
        .with_auth(self.auth)
        .with_recorder(recorder.clone())
        .with_rtk(rtk)
        .with_flight_logs_dir(recorder.dir().join("flight-logs"));
        if let Some(dds) = dds {
            state = dds.extend_api(state);
        }
        if let Some(t) = self.tls {
            state = state.with_tls(t);
        }
        if self.fetch_logs_after_landing {
            skein_api::log_autofetch::spawn(state.clone());
        }
        add_service(
            swarm,
            skein_api::ApiServer::service(listener.listener, state),
            "the API",
        )
        .await?;
        println!("skein: dashboard at {scheme}://{}/", listener.local);
        Ok(())
    }
}
