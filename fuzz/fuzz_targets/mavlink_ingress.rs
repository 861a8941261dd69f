//! MAVLink ingress: arbitrary bytes as UDP datagrams into a real `Endpoint` (the receive
//! task's own path, `Endpoint::ingest`): decoding, the MAVLink 2 signing check of a
//! signing vehicle, peer tracking, discovery and routing by sysid. Also the same bytes
//! as a byte stream (TCP / serial reassembly across chunk boundaries). Nothing may
//! panic, a routed frame reaches only its own vehicle's handler, and the decoder never
//! finds more frames than the bytes can hold (a MAVLink 1 frame is at least 8 bytes).
#![no_main]

use libfuzzer_sys::fuzz_target;
use skein_link::{ConnectionAddress, Endpoint, Identity};
use skein_mavlink::signing::{LinkSigning, SigningKey};
use skein_mavlink::{DecodeStats, Decoder};
use std::sync::{Arc, OnceLock};

struct Harness {
    _rt: tokio::runtime::Runtime,
    endpoint: Arc<Endpoint>,
}

fn harness() -> &'static Harness {
    static H: OnceLock<Harness> = OnceLock::new();
    H.get_or_init(|| {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        let address: ConnectionAddress = "udpin:127.0.0.1:0".parse().expect("address");
        let endpoint = rt
            .block_on(Endpoint::open(address, Identity::default()))
            .expect("endpoint");
        // Vehicles 1 and 2 are routed; 2 requires signing; 3 is known by discovery only.
        for sysid in [1u8, 2] {
            endpoint.route(
                sysid,
                Arc::new(move |frame| {
                    assert_eq!(frame.sysid, sysid, "frame routed to the wrong vehicle");
                }),
            );
        }
        endpoint.set_signing(
            Some(2),
            Arc::new(LinkSigning::new(SigningKey::from_bytes([7; 32]), 1)),
        );
        endpoint.set_discovery(Arc::new(|d| assert!(d.sysid != 0 || d.compid < 255)));
        Harness { _rt: rt, endpoint }
    })
}

fuzz_target!(|data: &[u8]| {
    let h = harness();
    // As datagrams: the first byte chooses where to cut (several datagrams per input).
    let (cut, body) = data.split_first().map_or((0, data), |(c, b)| (*c as usize, b));
    let mut decoder = Decoder::new(Arc::new(DecodeStats::default()));
    let parts: Vec<&[u8]> = if cut == 0 || body.is_empty() {
        vec![body]
    } else {
        body.chunks(cut).collect()
    };
    for part in &parts {
        h.endpoint.ingest(&mut decoder, part, Some("127.0.0.1:14540".parse().unwrap()));
    }
    // As a byte stream cut into the same chunks.
    let mut stream = Decoder::new(Arc::new(DecodeStats::default()));
    let mut frames = 0u64;
    for part in &parts {
        stream.push(part);
        while stream.next_frame().is_some() {
            frames += 1;
        }
    }
    assert!(frames <= body.len() as u64 / 8, "more frames than bytes allow");
});
