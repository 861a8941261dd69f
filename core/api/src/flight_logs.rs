//! The vehicles' flight logs (ULog) brought home through MAVLink's log protocol
//! ([`skein_link::log_transfer`]): `GET /api/v1/vehicles/{id}/logs` lists a vehicle's
//! logs, `POST …/logs/{log_id}/download` fetches one in the background (202),
//! `GET …/logs/{log_id}/file` serves its bytes once every one arrived, `GET
//! /api/v1/logs` shows every download, and `POST /api/v1/logs/fetch_latest` fetches the
//! newest log of every vehicle at once (one transfer per vehicle, all vehicles side by
//! side).
//!
//! A download is written to `<dir>/<vehicle>/log-<log_id>-<time_utc>.ulg` (`dir`: the
//! recordings' directory's `flight-logs`) through a `.part` file renamed when complete:
//! a file is complete or absent, never truncated. One transfer per vehicle at a time
//! (the vehicle's log handler serves one).

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::{VehicleId, VehicleLog};
use crate::px4_params::{ask_link, link_of};
use axum::Json;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use ractor::ActorRef;
use serde::Serialize;
use skein_link::log_transfer::LogEntry;
use skein_link::{LinkError, Px4LinkMsg};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// How long a listing may take (its resends through a link cut included: the link gives
/// up after 20 s).
const LIST_TIMEOUT: Duration = Duration::from_secs(25);

/// How long a download may take at most (a stalled one fails sooner, after 60 s
/// without a byte).
const DOWNLOAD_TIMEOUT: Duration = Duration::from_secs(3600);

/// Where a download stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum DownloadState {
    /// Bytes are arriving.
    Downloading,
    /// Every byte arrived; the file is written.
    Complete,
    /// It failed (`error` says why); asking again starts over.
    Failed,
}

/// One download, as the API shows it.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct LogDownloadStatus {
    /// Vehicle id.
    pub vehicle: String,
    /// The vehicle's log id.
    pub log_id: u16,
    /// Where it stands.
    pub state: DownloadState,
    /// The log's size, bytes.
    pub size_bytes: u32,
    /// Bytes received so far.
    pub received_bytes: u64,
    /// When the log was written, seconds since the Unix epoch (UTC).
    pub time_utc: u32,
    /// The file, once complete.
    pub path: Option<String>,
    /// Why it failed.
    pub error: Option<String>,
}

/// A download and its progress counter (the link counts into it).
struct Download {
    status: LogDownloadStatus,
    progress: Arc<AtomicU64>,
}

/// The downloads of this process (see the module docs).
pub struct FlightLogs {
    dir: PathBuf,
    downloads: Mutex<BTreeMap<(String, u16), Download>>,
}

impl FlightLogs {
    /// Downloads go to `dir`, one directory per vehicle.
    pub fn new(dir: PathBuf) -> Arc<Self> {
        Arc::new(FlightLogs {
            dir,
            downloads: Mutex::default(),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<(String, u16), Download>> {
        self.downloads
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    fn status(&self, vehicle: &str, log_id: u16) -> Option<LogDownloadStatus> {
        self.lock()
            .get(&(vehicle.to_string(), log_id))
            .map(snapshot)
    }

    fn all(&self) -> Vec<LogDownloadStatus> {
        self.lock().values().map(snapshot).collect()
    }

    /// Registers a download of `entry` of `vehicle`; `None` while this vehicle has one
    /// in progress (or this one is complete: its status is answered instead).
    fn begin(&self, vehicle: &str, entry: LogEntry) -> Result<Arc<AtomicU64>, LogDownloadStatus> {
        let mut all = self.lock();
        if let Some(busy) = all
            .values()
            .find(|d| d.status.vehicle == vehicle && d.status.state == DownloadState::Downloading)
        {
            return Err(snapshot(busy));
        }
        let key = (vehicle.to_string(), entry.id);
        if let Some(done) = all
            .get(&key)
            .filter(|d| d.status.state == DownloadState::Complete)
        {
            return Err(snapshot(done));
        }
        let progress = Arc::new(AtomicU64::new(0));
        let status = LogDownloadStatus {
            vehicle: vehicle.to_string(),
            log_id: entry.id,
            state: DownloadState::Downloading,
            size_bytes: entry.size_bytes,
            received_bytes: 0,
            time_utc: entry.time_utc,
            path: None,
            error: None,
        };
        let download = Download {
            status,
            progress: progress.clone(),
        };
        all.insert(key, download);
        Ok(progress)
    }

    fn end(&self, vehicle: &str, log_id: u16, outcome: Result<PathBuf, String>) {
        let mut all = self.lock();
        let Some(d) = all.get_mut(&(vehicle.to_string(), log_id)) else {
            return;
        };
        match outcome {
            Ok(path) => {
                d.status.state = DownloadState::Complete;
                d.status.path = Some(path.display().to_string());
            }
            Err(e) => {
                d.status.state = DownloadState::Failed;
                d.status.error = Some(e);
            }
        }
    }

    /// Writes `bytes` to the log's file through a `.part` file; returns its path.
    fn write(&self, vehicle: &str, entry: LogEntry, bytes: &[u8]) -> Result<PathBuf, String> {
        let dir = self.dir.join(vehicle);
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = dir.join(format!("log-{}-{}.ulg", entry.id, entry.time_utc));
        let part = path.with_extension("ulg.part");
        std::fs::write(&part, bytes).map_err(|e| format!("{}: {e}", part.display()))?;
        std::fs::rename(&part, &path).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path)
    }
}

fn snapshot(d: &Download) -> LogDownloadStatus {
    let mut s = d.status.clone();
    s.received_bytes = d.progress.load(Ordering::Relaxed);
    s
}

/// Lists `vehicle`'s logs through `link`: 409 while a transfer of it runs, 503 when
/// the vehicle does not answer.
async fn list(link: &ActorRef<Px4LinkMsg>, vehicle: &str) -> Result<Vec<LogEntry>, ApiError> {
    ask_link(link, Px4LinkMsg::LogList, LIST_TIMEOUT, vehicle)
        .await?
        .map_err(|e| transfer_error(vehicle, e))
}

fn transfer_error(vehicle: &str, e: LinkError) -> ApiError {
    match e {
        LinkError::Rejected { .. } => ApiError::conflict(format!("{vehicle}: {e}"), None),
        e => ApiError::unavailable(format!("{vehicle}: {e}")),
    }
}

/// Starts downloading `entry` of `vehicle` in the background.
fn spawn_download(
    logs: Arc<FlightLogs>,
    link: ActorRef<Px4LinkMsg>,
    vehicle: String,
    entry: LogEntry,
    progress: Arc<AtomicU64>,
) {
    tokio::spawn(async move {
        let asked = link
            .call(
                |r| Px4LinkMsg::LogDownload(entry.id, progress, r),
                Some(DOWNLOAD_TIMEOUT),
            )
            .await;
        let outcome = match asked {
            Ok(ractor::rpc::CallResult::Success(Ok(bytes))) => logs.write(&vehicle, entry, &bytes),
            Ok(ractor::rpc::CallResult::Success(Err(e))) => Err(e.to_string()),
            _ => Err("the vehicle's link stopped during the download".to_string()),
        };
        if let Err(e) = &outcome {
            tracing::warn!("{vehicle}: log {} download failed: {e}", entry.id);
        }
        logs.end(&vehicle, entry.id, outcome);
    });
}

/// A vehicle's flight logs
///
/// The vehicle's logs (MAVLink `LOG_REQUEST_LIST` → `LOG_ENTRY`), oldest first: `id`
/// (PX4's, from 0), `size_bytes`, `time_utc` (Unix seconds).
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/logs", params(VehicleId),
    responses((status = 200, body = [LogEntry]), (status = 404), (status = 409),
        (status = 503)))]
pub(crate) async fn list_logs(
    State(s): State<ApiState>,
    Path(VehicleId { id }): Path<VehicleId>,
) -> Result<Json<Vec<LogEntry>>, ApiError> {
    let link = link_of(&s, &id).await?;
    Ok(Json(list(&link, &id).await?))
}

/// Fetch one flight log
///
/// 202 with the download's status; it runs in the background (`GET /api/v1/logs`). A
/// log downloaded already answers 200 with its status; 404 names `log_id` when the
/// vehicle has no such log; 409 while another download of this vehicle runs.
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/logs/{log_id}/download", params(VehicleLog),
    responses((status = 202, body = LogDownloadStatus), (status = 200, body = LogDownloadStatus),
        (status = 400), (status = 404), (status = 409), (status = 503)))]
pub(crate) async fn download_log(
    State(s): State<ApiState>,
    Path(path): Path<VehicleLog>,
) -> Result<Response, ApiError> {
    let (log_id, id) = (path.log_id()?, path.id);
    let link = link_of(&s, &id).await?;
    let entries = list(&link, &id).await?;
    let Some(entry) = entries.iter().find(|e| e.id == log_id).copied() else {
        return Err(ApiError {
            status: StatusCode::NOT_FOUND,
            error: format!("{id} has no log {log_id} ({} logs)", entries.len()),
            field: Some("log_id".into()),
        });
    };
    start(&s, link, &id, entry)
}

fn start(
    s: &ApiState,
    link: ActorRef<Px4LinkMsg>,
    vehicle: &str,
    entry: LogEntry,
) -> Result<Response, ApiError> {
    match s.flight_logs.begin(vehicle, entry) {
        Ok(progress) => {
            spawn_download(s.flight_logs.clone(), link, vehicle.into(), entry, progress);
            let status = s.flight_logs.status(vehicle, entry.id);
            Ok((StatusCode::ACCEPTED, Json(status)).into_response())
        }
        Err(done) if done.state == DownloadState::Complete && done.log_id == entry.id => {
            Ok(Json(done).into_response())
        }
        Err(busy) => Err(ApiError::conflict(
            format!(
                "{vehicle}: log {} is downloading ({} of {} bytes); one transfer per vehicle",
                busy.log_id, busy.received_bytes, busy.size_bytes
            ),
            None,
        )),
    }
}

/// A downloaded flight log's file
///
/// The ULog bytes once every one arrived (`application/octet-stream`); 409 while the
/// download runs or after it failed, 404 for a log never asked for.
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/logs/{log_id}/file", params(VehicleLog),
    responses((status = 200, content_type = "application/octet-stream"), (status = 400),
        (status = 404), (status = 409)))]
pub(crate) async fn log_file(
    State(s): State<ApiState>,
    Path(path): Path<VehicleLog>,
) -> Result<Response, ApiError> {
    let (log_id, id) = (path.log_id()?, path.id);
    let Some(status) = s.flight_logs.status(&id, log_id) else {
        return Err(ApiError::not_found(format!(
            "log {log_id} of {id} was not downloaded (POST …/logs/{log_id}/download)"
        )));
    };
    let (DownloadState::Complete, Some(path)) = (status.state, status.path.as_ref()) else {
        return Err(ApiError::conflict(
            format!(
                "log {log_id} of {id} is {:?}: {} of {} bytes{}",
                status.state,
                status.received_bytes,
                status.size_bytes,
                status.error.map(|e| format!(" ({e})")).unwrap_or_default()
            ),
            None,
        ));
    };
    let file = path.clone();
    let bytes = tokio::task::spawn_blocking(move || std::fs::read(&file))
        .await
        .map_err(|e| ApiError::status(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
        .map_err(|e| ApiError::status(StatusCode::INTERNAL_SERVER_ERROR, format!("{path}: {e}")))?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

/// Every flight log download
#[utoipa::path(get, path = "/api/v1/logs",
    responses((status = 200, body = [LogDownloadStatus])))]
pub(crate) async fn downloads(State(s): State<ApiState>) -> Json<Vec<LogDownloadStatus>> {
    Json(s.flight_logs.all())
}

/// Fetch the newest log of every vehicle
///
/// Lists every vehicle's logs and downloads the newest of each, every vehicle side by
/// side; 202 with the downloads started (or found complete). A vehicle that does not
/// answer, has no log or is busy is named in `skipped` with the reason.
#[utoipa::path(post, path = "/api/v1/logs/fetch_latest",
    responses((status = 202, body = FetchLatest)))]
pub(crate) async fn fetch_latest(State(s): State<ApiState>) -> Result<Response, ApiError> {
    // Every vehicle's listing at once (a vehicle without logs answers only by silence).
    let asked: Vec<_> = s
        .reads
        .vehicles()
        .into_iter()
        .map(|v| {
            let s = s.clone();
            tokio::spawn(async move { (fetch_newest(&s, &v.id).await, v.id) })
        })
        .collect();
    let mut out = FetchLatest::default();
    for task in asked {
        match task.await {
            Ok((Ok(status), _)) => out.downloads.push(status),
            Ok((Err(e), id)) => {
                out.skipped.insert(id, e.error);
            }
            Err(e) => return Err(ApiError::unavailable(format!("a listing failed: {e}"))),
        }
    }
    Ok((StatusCode::ACCEPTED, Json(out)).into_response())
}

pub(crate) async fn fetch_newest(
    s: &ApiState,
    vehicle: &str,
) -> Result<LogDownloadStatus, ApiError> {
    let link = link_of(s, vehicle).await?;
    let entries = list(&link, vehicle).await?;
    let Some(newest) = entries.iter().max_by_key(|e| (e.time_utc, e.id)).copied() else {
        return Err(ApiError::not_found(format!("{vehicle} has no log")));
    };
    start(s, link, vehicle, newest)?;
    s.flight_logs
        .status(vehicle, newest.id)
        .ok_or_else(|| ApiError::unavailable(format!("{vehicle}: the download vanished")))
}

/// What `POST /api/v1/logs/fetch_latest` started.
#[derive(Debug, Default, Serialize, utoipa::ToSchema)]
pub struct FetchLatest {
    /// The downloads, one per vehicle.
    pub downloads: Vec<LogDownloadStatus>,
    /// Vehicles not fetched, with why.
    pub skipped: BTreeMap<String, String>,
}
