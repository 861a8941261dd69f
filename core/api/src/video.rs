//! A camera payload's frames over HTTP: the last frame as JPEG
//! (`GET /api/v1/vehicles/{id}/payloads/{slot}/snapshot`) and every new one as MJPEG
//! (`…/stream`, `multipart/x-mixed-replace`), which an `<img>` shows as video.

use crate::ApiState;
use crate::error::ApiError;
use crate::path_params::PayloadSlot;
use crate::responses::Binary;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use skein_swarm::PayloadMsg;

async fn payload_of(
    s: &ApiState,
    id: String,
    slot: String,
) -> Result<std::sync::Arc<skein_swarm::payload::PayloadShared>, ApiError> {
    s.ask(move |r| PayloadMsg::GetPayload(id, slot, r).into())
        .await?
        .map_err(ApiError::not_found)
}

/// The camera's last frame
///
/// 404 before the first.
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/payloads/{slot}/snapshot",
    params(PayloadSlot),
    responses((status = 200, body = inline(Binary), content_type = "image/jpeg"), (status = 404),
        (status = 503)))]
pub(crate) async fn payload_snapshot(
    State(s): State<ApiState>,
    Path(PayloadSlot { id, slot }): Path<PayloadSlot>,
) -> Result<Response, ApiError> {
    let p = payload_of(&s, id.clone(), slot.clone()).await?;
    match p.frame() {
        Some(jpeg) => Ok((
            [
                (header::CONTENT_TYPE, "image/jpeg"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            jpeg.as_ref().clone(),
        )
            .into_response()),
        None => Err(ApiError::not_found(format!(
            "payload `{slot}` of {id} has published no frame yet"
        ))),
    }
}

/// Boundary of the MJPEG multipart stream.
const MJPEG_BOUNDARY: &str = "skeinframe";

/// The camera's frames as MJPEG, every new one
///
/// The current frame first, then every new one, until the payload is gone.
#[utoipa::path(get, path = "/api/v1/vehicles/{id}/payloads/{slot}/stream",
    params(PayloadSlot),
    responses((status = 200, body = inline(Binary), content_type = "multipart/x-mixed-replace"),
        (status = 404), (status = 503)))]
pub(crate) async fn payload_stream(
    State(s): State<ApiState>,
    Path(PayloadSlot { id, slot }): Path<PayloadSlot>,
) -> Result<Response, ApiError> {
    let p = payload_of(&s, id, slot).await?;
    let rx = p.subscribe_frames();
    // Each part is sent once: the current frame first, then every new one.
    let frames = futures_util::stream::unfold((rx, true), |(mut rx, first)| async move {
        loop {
            if !first && rx.changed().await.is_err() {
                return None; // the payload is gone
            }
            let frame = rx.borrow_and_update().clone();
            let Some(jpeg) = frame else {
                if first {
                    // Nothing yet: wait for the first frame.
                    if rx.changed().await.is_err() {
                        return None;
                    }
                    continue;
                }
                continue;
            };
            let mut part = format!(
                "--{MJPEG_BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
                jpeg.len()
            )
            .into_bytes();
            part.extend_from_slice(&jpeg);
            part.extend_from_slice(b"\r\n");
            return Some((
                Ok::<_, std::convert::Infallible>(Bytes::from(part)),
                (rx, false),
            ));
        }
    });
    let body = axum::body::Body::from_stream(frames);
    Ok((
        [
            (
                header::CONTENT_TYPE,
                format!("multipart/x-mixed-replace; boundary={MJPEG_BOUNDARY}"),
            ),
            (header::CACHE_CONTROL, "no-store".to_string()),
        ],
        body,
    )
        .into_response())
}
