//! The client against the simulator's server (`skein_sim::ftp_server`, PX4's
//! `MavlinkFTP`) in memory, on a virtual clock: clean, lossy, reordered and dead links,
//! and the NAKs.

use super::*;
use skein_sim::ftp_server::FtpServer;
use std::sync::OnceLock;

/// 100 kB of pseudo-random bytes: three bursts of PX4's 35 kB.
fn big() -> &'static [u8] {
    static FILE: OnceLock<Vec<u8>> = OnceLock::new();
    FILE.get_or_init(|| {
        let mut x = 0x1234_5678u32;
        (0..100_000)
            .map(|_| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 24) as u8
            })
            .collect()
    })
}

fn files(path: &str) -> Option<&'static [u8]> {
    match path {
        "etc/extras/big.bin" => Some(big()),
        "etc/extras/small.bin" => Some(&big()[..1000]),
        _ => None,
    }
}

/// A link that loses one message in `loss` (0: none), swaps neighbours when `reorder`.
struct Channel {
    loss: u32,
    reorder: bool,
    rng: u32,
}

impl Channel {
    fn pass<T>(&mut self, mut msgs: Vec<T>) -> Vec<T> {
        if self.loss > 0 {
            msgs.retain(|_| {
                self.rng = self.rng.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                !(self.rng >> 16).is_multiple_of(self.loss)
            });
        }
        if self.reorder {
            for i in (1..msgs.len()).step_by(2) {
                msgs.swap(i - 1, i);
            }
        }
        msgs
    }
}

/// Runs a read of `path` against `server` for at most 120 s of virtual time.
fn read(
    server: &mut FtpServer,
    path: &str,
    mut ch: Channel,
) -> (Result<Vec<u8>, FtpError>, FtpStats) {
    let mut now = Instant::now();
    let mut client = FtpRead::new(path, now);
    for _ in 0..12_000 {
        let mut replies = Vec::new();
        for req in ch.pass(client.take_outgoing()) {
            replies.extend(server.handle(&req, (255, 190), now));
        }
        replies.extend(server.pump(now, 8).into_iter().map(|(_, p)| p));
        for p in ch.pass(replies) {
            if let Some(done) = client.on_reply(&p, now) {
                return (done, client.stats());
            }
        }
        now += Duration::from_millis(10);
        if let Some(done) = client.on_tick(now) {
            return (done, client.stats());
        }
    }
    panic!("no outcome in 120 s");
}

#[test]
fn a_file_comes_whole_in_bursts_of_35_kb() {
    let mut server = FtpServer::new(files);
    let (data, stats) = read(
        &mut server,
        "etc/extras/big.bin",
        Channel {
            loss: 0,
            reorder: false,
            rng: 1,
        },
    );
    assert_eq!(data.unwrap(), big());
    assert_eq!(
        (stats.bursts, stats.reads, stats.retries),
        (3, 0, 0),
        "{stats:?}"
    );
}

#[test]
fn a_lossy_reordering_link_costs_retries_not_bytes() {
    for (loss, seed) in [(5, 7), (10, 11)] {
        let mut server = FtpServer::new(files);
        let ch = Channel {
            loss,
            reorder: true,
            rng: seed,
        };
        let (data, stats) = read(&mut server, "etc/extras/big.bin", ch);
        assert_eq!(data.unwrap(), big(), "1 in {loss} lost");
        assert!(
            stats.bursts + stats.reads > 3,
            "gaps were asked for again: {stats:?}"
        );
    }
}

#[test]
fn naks_name_the_missing_file_and_a_session_left_open_is_reset() {
    let mut server = FtpServer::new(files);
    let (err, _) = read(
        &mut server,
        "etc/extras/nothing.json",
        Channel {
            loss: 0,
            reorder: false,
            rng: 1,
        },
    );
    let err = err.unwrap_err();
    assert!(err.to_string().contains("etc/extras/nothing.json"), "{err}");
    assert!(err.reason.contains("FileNotFound"), "{err}");
    // Another client opened a file and went away: PX4 refuses a second session.
    let open = FtpPayload::request(40, 0, Opcode::OpenFileRO, 0, b"etc/extras/small.bin");
    assert_eq!(
        server.handle(&open, (1, 1), Instant::now()).unwrap().opcode,
        Opcode::Ack
    );
    let (data, stats) = read(
        &mut server,
        "etc/extras/small.bin",
        Channel {
            loss: 0,
            reorder: false,
            rng: 1,
        },
    );
    assert_eq!(data.unwrap(), &big()[..1000]);
    assert!(stats.requests >= 4, "open, reset, open, burst: {stats:?}");
}

#[test]
fn a_dead_link_fails_with_a_clear_error() {
    let mut server = FtpServer::new(files);
    let (err, stats) = read(
        &mut server,
        "etc/extras/big.bin",
        Channel {
            loss: 1,
            reorder: false,
            rng: 1,
        },
    );
    let err = err.unwrap_err();
    assert!(err.reason.contains("no answer to OpenFileRO"), "{err}");
    assert_eq!(stats.retries, MAX_TRIES - 1);
}
