//! The simulator's I/O: one UDP socket and one receive task per vehicle, and a few shard
//! tasks that step physics and send telemetry for groups of vehicles at the tick rate.
//!
//! Receive tasks take each datagram with the kernel's arrival stamp ([`crate::arrival`])
//! and only hold the vehicle's lock while decoding it; shard ticks are short (a few dozen vehicles each, with
//! staggered phases) so they never starve the receivers. Frames due in one tick are batched
//! into as few datagrams as possible (split at frame boundaries below a typical MTU) and
//! sent with a non-blocking `try_send_to`; a full socket buffer drops the datagram and
//! counts it, as PX4's `tx_overflows` does.
//!
//! A simulated link quality ([`Impairment`]) sits between the socket and the vehicle: the
//! loss draw happens as a datagram arrives or leaves, and with a latency set, datagrams of
//! both directions wait in the vehicle's delay lines, which its receive task drains when
//! they fall due (it sleeps until the earliest due time, or is woken when an outbound
//! datagram enters an empty line).

use crate::impairment::Impairment;
use crate::px4_params::Param;
use crate::signing::SimSigning;
use crate::vehicle::{Outbox, Vehicle};
use skein_mavlink::{DecodeCounts, DecodeStats, Decoder, Encoder};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;
use tokio::task::JoinHandle;

/// Largest datagram the simulator sends (fits a 1500-byte Ethernet MTU).
const MAX_DATAGRAM: usize = 1472;
/// Vehicles stepped by one shard task.
pub(crate) const SHARD_SIZE: usize = 32;

/// Network counters of one vehicle's socket.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct NetCounters {
    pub datagrams_received: u64,
    pub bytes_received: u64,
    pub datagrams_dropped_silent: u64,
    pub datagrams_sent: u64,
    pub bytes_sent: u64,
    pub frames_sent: u64,
    pub send_drops: u64,
}

/// Mutable state of one vehicle, behind its lock.
pub(crate) struct Slot {
    pub vehicle: Vehicle,
    pub encoder: Encoder,
    /// The first sender heard from: replies go there from then on.
    pub peer: Option<SocketAddr>,
    /// Link cut state.
    pub silence: Silence,
    pub killed: bool,
    pub socket: Option<Arc<UdpSocket>>,
    pub out: Vec<u8>,
    pub net: NetCounters,
    pub decode_baseline: DecodeCounts,
    /// Simulated link quality and delay lines.
    pub impair: Impairment,
    /// MAVLink 2 signing (key, counters).
    pub signing: SimSigning,
}

/// Whether a vehicle's link is cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Silence {
    Off,
    Until(Instant),
    Forever,
}

impl Slot {
    pub fn is_silent(&mut self, now: Instant) -> bool {
        match self.silence {
            Silence::Off => false,
            Silence::Forever => true,
            Silence::Until(until) if now < until => true,
            Silence::Until(_) => {
                self.silence = Silence::Off;
                false
            }
        }
    }

    /// Sends what is in `out` (one or more datagrams) unless silent; clears `out`. Each
    /// datagram goes through the link's loss draw and, with a latency, its delay line.
    pub fn flush(&mut self, now: Instant, target: SocketAddr) {
        if self.out.is_empty() {
            return;
        }
        let silent = self.is_silent(now);
        let Some(socket) = self.socket.clone().filter(|_| !silent && !self.killed) else {
            self.out.clear();
            return;
        };
        let dest = self.peer.unwrap_or(target);
        let buf = std::mem::take(&mut self.out);
        let mut start = 0;
        let mut pos = 0;
        let mut frames = 0u64;
        while pos < buf.len() {
            // Every frame in `out` is a MAVLink 2 frame we encoded ourselves: header,
            // payload, CRC, and the signature when the signed flag is set.
            let signature = if buf.get(pos + 2).is_some_and(|f| f & 1 != 0) {
                13
            } else {
                0
            };
            let len = usize::from(buf.get(pos + 1).copied().unwrap_or(0)) + 12 + signature;
            let end = (pos + len).min(buf.len());
            if end - start > MAX_DATAGRAM && pos > start {
                self.emit(&socket, now, dest, &buf[start..pos]);
                start = pos;
            }
            pos = end;
            frames += 1;
        }
        if pos > start {
            self.emit(&socket, now, dest, &buf[start..pos]);
        }
        self.net.frames_sent += frames;
        let link = &mut self.vehicle.link;
        link.tx_frames += frames;
        link.tx_bytes += buf.len() as u64;
        link.tx_overflows = self.net.send_drops;
        self.out = buf;
        self.out.clear();
    }

    /// One datagram out: lost, delayed, or sent now.
    fn emit(&mut self, socket: &UdpSocket, now: Instant, dest: SocketAddr, datagram: &[u8]) {
        if self.impair.lose(false) {
            return;
        }
        if self.impair.delays_outbound() {
            self.impair.push_outbound(now, dest, datagram);
        } else {
            self.send_now(socket, dest, datagram);
        }
    }

    fn send_now(&mut self, socket: &UdpSocket, dest: SocketAddr, datagram: &[u8]) {
        match socket.try_send_to(datagram, dest) {
            Ok(n) => {
                self.net.datagrams_sent += 1;
                self.net.bytes_sent += n as u64;
            }
            Err(_) => self.net.send_drops += 1,
        }
    }

    /// A datagram that reached the vehicle (after the link's loss and delay): counted,
    /// decoded, handled; replies flushed.
    fn receive(
        &mut self,
        cell: &Cell,
        decoder: &mut Decoder,
        datagram: &[u8],
        from: SocketAddr,
        now: Instant,
    ) {
        if self.is_silent(now) {
            self.net.datagrams_dropped_silent += 1;
            return;
        }
        let n = datagram.len();
        self.net.datagrams_received += 1;
        self.net.bytes_received += n as u64;
        self.vehicle.link.rx_bytes += n as u64;
        if self.peer.is_none() {
            self.peer = Some(from);
        }
        {
            let vehicle = &mut self.vehicle;
            let signing = &mut self.signing;
            let mut out = Outbox {
                enc: &mut self.encoder,
                buf: &mut self.out,
                frames: 0,
            };
            decoder.decode_datagram_raw(datagram, |frame, raw| {
                let required = vehicle.params.get(Param::MAV_SIGN_CFG) != 0.0;
                if !signing.accept(raw, required) {
                    return;
                }
                if signing.on_message(&frame.msg) {
                    out.enc.set_signing(signing.current.clone());
                    return;
                }
                vehicle.handle_frame(now, &frame, &mut out);
            });
            vehicle.link.rx_parse_errors = cell
                .decode_stats
                .snapshot()
                .errors()
                .saturating_sub(self.decode_baseline.errors());
        }
        self.flush(now, cell.target);
        if self.vehicle.reboot_requested {
            self.reboot(now);
        }
    }

    /// A datagram from the socket: through the loss draw, then delayed or received now.
    fn arrive(
        &mut self,
        cell: &Cell,
        decoder: &mut Decoder,
        datagram: &[u8],
        from: SocketAddr,
        now: Instant,
    ) {
        if self.impair.lose(true) {
            return;
        }
        if self.impair.delays_inbound() {
            self.impair.push_inbound(now, from, datagram);
        } else {
            self.receive(cell, decoder, datagram, from, now);
        }
    }

    /// Delivers what is due in both delay lines (outbound datagrams still need an open
    /// socket; they were sent before any link cut, so a cut does not stop them).
    fn drain_due(&mut self, cell: &Cell, decoder: &mut Decoder, now: Instant) {
        while let Some(d) = self.impair.pop_inbound(now) {
            self.receive(cell, decoder, &d.bytes, d.addr, now);
        }
        while let Some(d) = self.impair.pop_outbound(now) {
            if let Some(socket) = self.socket.clone().filter(|_| !self.killed) {
                self.send_now(&socket, d.addr, &d.bytes);
            }
        }
    }

    /// One simulation tick: step, then stream what is due.
    pub fn tick(&mut self, now: Instant, dt_s: f64, target: SocketAddr) {
        let mut out = Outbox {
            enc: &mut self.encoder,
            buf: &mut self.out,
            frames: 0,
        };
        self.vehicle.step(now, dt_s, &mut out);
        self.vehicle.emit_due_streams(now, &mut out);
        self.flush(now, target);
    }

    /// PX4 reboot: fresh state, boot time and sequence numbers; forgets the locked peer.
    pub fn reboot(&mut self, now: Instant) {
        self.vehicle.reboot(now);
        self.encoder = Encoder::new(self.vehicle.sysid, 1);
        self.encoder.set_signing(self.signing.current.clone());
        self.peer = None;
        self.out.clear();
    }
}

/// One vehicle: its identity, endpoints and locked state.
pub(crate) struct Cell {
    pub sysid: u8,
    pub bound: SocketAddr,
    pub target: SocketAddr,
    pub slot: Mutex<Slot>,
    pub decode_stats: Arc<DecodeStats>,
    pub recv_task: Mutex<Option<JoinHandle<()>>>,
}

impl Cell {
    /// Locks the slot, recovering from a poisoned lock (a panic elsewhere must not take
    /// the whole simulator down).
    pub fn lock(&self) -> MutexGuard<'_, Slot> {
        self.slot.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Receive loop of one vehicle; also drains its delay lines.
pub(crate) async fn recv_loop(cell: Arc<Cell>, socket: Arc<UdpSocket>) {
    let mut buf = vec![0u8; 65_536];
    let mut decoder = Decoder::new(cell.decode_stats.clone());
    let wake = cell.lock().impair.wake.clone();
    let notified = wake.notified();
    tokio::pin!(notified);
    let sleep = tokio::time::sleep(Duration::ZERO);
    tokio::pin!(sleep);
    let mut next_due: Option<Instant> = None;
    loop {
        let received = tokio::select! {
            biased;
            r = crate::arrival::recv_stamped(&socket, &mut buf) => match r {
                Ok(x) => Some(x),
                Err(e) => {
                    // ICMP errors and the like: keep serving, but do not spin.
                    tracing::debug!(sysid = cell.sysid, error = %e, "udp receive error");
                    tokio::time::sleep(Duration::from_millis(5)).await;
                    None
                }
            },
            () = &mut notified => {
                notified.set(wake.notified());
                None
            }
            () = &mut sleep, if next_due.is_some() => None,
        };
        let now = Instant::now();
        let mut guard = cell.lock();
        let slot = &mut *guard;
        if slot.killed {
            return;
        }
        if let Some((n, from, arrived)) = received {
            slot.arrive(&cell, &mut decoder, &buf[..n], from, arrived.min(now));
        }
        slot.drain_due(&cell, &mut decoder, now);
        let due = slot.impair.next_due();
        drop(guard);
        if let Some(d) = due
            && (Some(d) != next_due || sleep.is_elapsed())
        {
            sleep.as_mut().reset(tokio::time::Instant::from_std(d));
        }
        next_due = due;
    }
}

/// Tick loop of one shard of vehicles.
pub(crate) async fn shard_loop(
    cells: Vec<Arc<Cell>>,
    period: Duration,
    phase: Duration,
    stop: Arc<AtomicBool>,
) {
    tokio::time::sleep(phase).await;
    let mut interval = tokio::time::interval(period);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
    let dt_s = period.as_secs_f64();
    loop {
        interval.tick().await;
        if stop.load(Ordering::Relaxed) {
            return;
        }
        let now = Instant::now();
        for cell in &cells {
            let mut slot = cell.lock();
            if slot.killed {
                continue;
            }
            slot.tick(now, dt_s, cell.target);
        }
    }
}
