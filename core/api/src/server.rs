//! The API as a supervised actor.
//!
//! The coordinator supervises the HTTP server like any other child: a panic or a hang
//! restarts it by policy. The listening socket outlives the actor (the restarted server
//! accepts on the same port, clients never see "connection refused"); only the server
//! task is replaced: the old one stops accepting and gets [`DRAIN`] to finish the
//! requests in flight (the answer to the very request that injected the fault among
//! them) before it is aborted. Long-lived streams end then; the dashboard reconnects.

use crate::{ApiState, app};
use axum::serve::ListenerExt;
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};
use skein_model::supervision::ChildKind;
use skein_swarm::{ServiceMsg, ServiceSpec};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::watch;
use tokio::task::JoinHandle;

/// How long a replaced server may finish its requests in flight.
pub const DRAIN: Duration = Duration::from_secs(2);

/// A running server task and the switch that tells it to stop accepting.
struct Running {
    task: JoinHandle<()>,
    stop: watch::Sender<bool>,
}

impl Running {
    /// Stops accepting now, aborts after [`DRAIN`].
    fn retire(self) {
        let _ = self.stop.send(true);
        let task = self.task;
        tokio::spawn(async move {
            tokio::time::sleep(DRAIN).await;
            task.abort();
        });
    }
}

/// What survives restarts of the API actor: the bound listener, the handlers' state and
/// the current server task.
pub struct Persistent {
    listener: std::net::TcpListener,
    state: ApiState,
    running: Mutex<Option<Running>>,
}

/// The API server actor.
pub struct ApiServer;

/// Arguments of [`ApiServer`].
pub struct ApiServerArgs(Arc<Persistent>);

impl ApiServer {
    /// The service spec the coordinator starts and supervises: serves [`app`] on
    /// `listener` (already bound, so the address is known before anything starts).
    pub fn service(listener: std::net::TcpListener, state: ApiState) -> ServiceSpec {
        let persistent = Arc::new(Persistent {
            listener,
            state,
            running: Mutex::new(None),
        });
        ServiceSpec {
            name: "api".into(),
            kind: ChildKind::Api,
            spawn: Arc::new(move |supervisor: ActorCell| {
                let p = persistent.clone();
                Box::pin(async move {
                    let (actor, _) =
                        Actor::spawn_linked(None, ApiServer, ApiServerArgs(p), supervisor).await?;
                    Ok(actor)
                })
            }),
        }
    }
}

impl Actor for ApiServer {
    type Msg = ServiceMsg;
    type State = Arc<Persistent>;
    type Arguments = ApiServerArgs;

    async fn pre_start(
        &self,
        _myself: ActorRef<Self::Msg>,
        args: ApiServerArgs,
    ) -> Result<Self::State, ActorProcessingErr> {
        let p = args.0;
        let mut running = p.running.lock().unwrap_or_else(PoisonError::into_inner);
        // A killed or failed predecessor never ran post_stop: its server may still run.
        if let Some(old) = running.take() {
            old.retire();
        }
        let std_listener = p.listener.try_clone()?;
        std_listener.set_nonblocking(true)?;
        let listener = tokio::net::TcpListener::from_std(std_listener)?;
        let router = app(p.state.clone());
        let tls = p.state.tls.clone();
        let (stop, mut stopped) = watch::channel(false);
        let task = tokio::spawn(async move {
            let shutdown = async move {
                let _ = stopped.wait_for(|s| *s).await;
            };
            let service = router.into_make_service_with_connect_info::<std::net::SocketAddr>();
            let served = match tls {
                Some(config) => match crate::tls::TlsListener::new(listener, config) {
                    // tap_io: axum gives the connect info of any listener wrapped so.
                    Ok(l) => {
                        axum::serve(l.tap_io(|_| {}), service)
                            .with_graceful_shutdown(shutdown)
                            .await
                    }
                    Err(e) => Err(e),
                },
                None => {
                    axum::serve(listener, service)
                        .with_graceful_shutdown(shutdown)
                        .await
                }
            };
            if let Err(e) = served {
                tracing::error!("http server: {e}");
            }
        });
        *running = Some(Running { task, stop });
        drop(running);
        Ok(p)
    }

    async fn post_stop(
        &self,
        _myself: ActorRef<Self::Msg>,
        state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        if let Some(r) = state
            .running
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take()
        {
            r.retire();
        }
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<Self::Msg>,
        msg: Self::Msg,
        _state: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        msg.serve(&myself, "coordinator/api").await
    }
}
