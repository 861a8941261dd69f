//! One timer per period for the periodic messages of every actor in a swarm process
//! (control ticks, watchdog ticks, the formation tick), instead of a timer task per actor
//! and per period.
//!
//! Two things follow from having one clock:
//!
//! - **Cost.** A thousand vehicles ticking at 50 Hz cost a thousand timer tasks woken
//!   50 times a second each, on top of the actors themselves; one clock per period costs
//!   50 timer wake-ups a second, and each tick is one `cast` per actor.
//! - **No backlog.** A periodic message is only sent when the previous one has been
//!   handled ([`TickGate`]): an actor that cannot keep up (the process is short of CPU)
//!   misses ticks, counted as overruns ([`Ticker::overruns`]), instead of finding its
//!   mailbox filling with stale ticks that delay every other message (watchdog pings,
//!   commands) further and further. Each actor calls [`TickGate::done`] when it handles
//!   its tick.
//!
//! Work that needs no actor of its own runs on the clock itself ([`Ticker::run_every`]):
//! every vehicle's control step is a direct call there, not a message, so a control
//! period costs one task wake-up for the whole swarm instead of one per vehicle. A clock
//! that runs late (its own period overrun, the process short of CPU) counts the periods it
//! missed as overruns of each of its direct entries.
//!
//! A clock runs on the runtime of the first actor that registers with it; dropping the
//! [`Ticker`] stops its clocks.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

/// Sends one periodic message; returns false once its actor is gone (the entry is then
/// dropped).
type Fire = Box<dyn Fn() -> bool + Send + Sync>;

struct Entry {
    /// Set while the message sent is not handled yet; `None` for direct work, which is
    /// done by the time `fire` returns.
    pending: Option<Arc<AtomicBool>>,
    fire: Fire,
}

#[derive(Default)]
struct Clock {
    entries: Mutex<Vec<Entry>>,
}

/// A clock and the task that runs it.
type Running = (Arc<Clock>, JoinHandle<()>);

#[derive(Default)]
struct Inner {
    /// One clock per period, µs.
    clocks: Mutex<BTreeMap<u64, Running>>,
    /// Ticks not sent because the previous one was still waiting, and periods of direct
    /// work missed by a late clock.
    overruns: AtomicU64,
    /// Ticks sent and rounds of direct work done.
    sent: AtomicU64,
}

/// The clocks of one swarm process (see the module docs). Cheap to clone.
#[derive(Clone, Default)]
pub struct Ticker {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for Ticker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ticker")
            .field("overruns", &self.overruns())
            .finish_non_exhaustive()
    }
}

/// The receiving actor's side of one periodic message: it says when it has handled the
/// tick, which lets the next one be sent.
#[derive(Debug, Clone)]
pub struct TickGate(Arc<AtomicBool>);

impl TickGate {
    /// The tick has been handled: the next one may be sent.
    pub fn done(&self) {
        self.0.store(false, Ordering::Release);
    }
}

impl Ticker {
    /// A ticker with no clocks yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Calls `fire` every `period` (at least 1 ms) while the previous call's tick has
    /// been handled ([`TickGate::done`]), until `fire` returns false. Must be called on a
    /// tokio runtime (the first registration of a period starts its clock there).
    pub fn every(
        &self,
        period: Duration,
        fire: impl Fn() -> bool + Send + Sync + 'static,
    ) -> TickGate {
        let pending = Arc::new(AtomicBool::new(false));
        self.register(
            period,
            Entry {
                pending: Some(pending.clone()),
                fire: Box::new(fire),
            },
        );
        TickGate(pending)
    }

    /// Calls `work` on the clock's task every `period` (at least 1 ms), until it returns
    /// false. `work` runs beside every other direct entry of the period, one after the
    /// other: it must be short and must not block (a control step, not I/O). Must be
    /// called on a tokio runtime, as [`Ticker::every`].
    pub fn run_every(&self, period: Duration, work: impl Fn() -> bool + Send + Sync + 'static) {
        self.register(
            period,
            Entry {
                pending: None,
                fire: Box::new(work),
            },
        );
    }

    fn register(&self, period: Duration, entry: Entry) {
        let period = period.max(Duration::from_millis(1));
        let mut clocks = self.inner.clocks.lock().expect("ticker lock");
        let key = period.as_micros() as u64;
        let clock = match clocks.get(&key) {
            Some((clock, _)) => clock.clone(),
            None => {
                let clock = Arc::new(Clock::default());
                let task = tokio::spawn(run(
                    period,
                    Arc::downgrade(&clock),
                    Arc::downgrade(&self.inner),
                ));
                clocks.insert(key, (clock.clone(), task));
                clock
            }
        };
        clock.entries.lock().expect("clock lock").push(entry);
    }

    /// Ticks skipped so far because the actor had not handled the previous one, and
    /// periods of direct work ([`Ticker::run_every`]) missed because the clock ran late.
    pub fn overruns(&self) -> u64 {
        self.inner.overruns.load(Ordering::Relaxed)
    }

    /// Ticks sent and rounds of direct work done so far.
    pub fn sent(&self) -> u64 {
        self.inner.sent.load(Ordering::Relaxed)
    }

    /// Periodic messages registered and still alive (their actors running).
    pub fn registered(&self) -> usize {
        let clocks = self.inner.clocks.lock().expect("ticker lock");
        clocks
            .values()
            .map(|(c, _)| c.entries.lock().expect("clock lock").len())
            .sum()
    }
}

impl Drop for Inner {
    fn drop(&mut self) {
        let clocks = self.clocks.get_mut().expect("ticker lock");
        for (_, task) in clocks.values() {
            task.abort();
        }
    }
}

async fn run(period: Duration, clock: std::sync::Weak<Clock>, inner: std::sync::Weak<Inner>) {
    let mut interval = tokio::time::interval(period);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    interval.tick().await; // the first tick is immediate
    let mut last = tokio::time::Instant::now();
    loop {
        interval.tick().await;
        let now = tokio::time::Instant::now();
        // Whole periods this clock missed (it ran late): each direct entry missed them.
        let missed = (now.duration_since(last).as_secs_f64() / period.as_secs_f64() - 1.0)
            .round()
            .max(0.0) as u64;
        last = now;
        let (Some(clock), Some(inner)) = (clock.upgrade(), inner.upgrade()) else {
            return;
        };
        // Taken out of the lock while they run: a registration (an actor starting) never
        // waits for a round, and work that registers cannot deadlock.
        let mut entries = std::mem::take(&mut *clock.entries.lock().expect("clock lock"));
        let (mut sent, mut overruns) = (0, 0);
        entries.retain(|e| match &e.pending {
            Some(pending) if pending.swap(true, Ordering::AcqRel) => {
                overruns += 1;
                true
            }
            Some(_) => {
                sent += 1;
                (e.fire)()
            }
            None => {
                overruns += missed;
                sent += 1;
                (e.fire)()
            }
        });
        {
            let mut current = clock.entries.lock().expect("clock lock");
            // Registered while the round ran: after the others.
            entries.append(&mut current);
            *current = entries;
        }
        inner.sent.fetch_add(sent, Ordering::Relaxed);
        inner.overruns.fetch_add(overruns, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    #[tokio::test(start_paused = true)]
    async fn a_tick_waits_for_the_previous_one_to_be_handled() {
        let ticker = Ticker::new();
        let fired = Arc::new(AtomicUsize::new(0));
        let f = fired.clone();
        let gate = ticker.every(Duration::from_millis(20), move || {
            f.fetch_add(1, Ordering::Relaxed);
            true
        });
        tokio::time::sleep(Duration::from_millis(105)).await;
        // Never handled: one tick sent, the next four skipped.
        assert_eq!(fired.load(Ordering::Relaxed), 1);
        assert_eq!(ticker.overruns(), 4);
        gate.done();
        tokio::time::sleep(Duration::from_millis(20)).await;
        assert_eq!(fired.load(Ordering::Relaxed), 2);
    }

    #[tokio::test(start_paused = true)]
    async fn handled_ticks_come_every_period_and_stop_with_their_actor() {
        let ticker = Ticker::new();
        let fired = Arc::new(AtomicUsize::new(0));
        let alive = Arc::new(AtomicBool::new(true));
        let gate_slot: Arc<Mutex<Option<TickGate>>> = Arc::default();
        let (f, a, g) = (fired.clone(), alive.clone(), gate_slot.clone());
        let gate = ticker.every(Duration::from_millis(10), move || {
            f.fetch_add(1, Ordering::Relaxed);
            // The actor handles its tick at once.
            if let Some(g) = g.lock().unwrap().as_ref() {
                g.done();
            }
            a.load(Ordering::Relaxed)
        });
        *gate_slot.lock().unwrap() = Some(gate);
        // A second registration on the same period shares the clock.
        ticker.every(Duration::from_millis(10), || false);
        tokio::time::sleep(Duration::from_millis(55)).await;
        assert_eq!(fired.load(Ordering::Relaxed), 5);
        assert_eq!(ticker.overruns(), 0);
        assert_eq!(
            ticker.registered(),
            1,
            "the one whose actor is gone was dropped"
        );
        alive.store(false, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_millis(30)).await;
        assert_eq!(ticker.registered(), 0);
        assert_eq!(fired.load(Ordering::Relaxed), 6);
    }

    #[tokio::test(start_paused = true)]
    async fn direct_work_runs_on_the_clock_and_counts_the_periods_a_late_clock_missed() {
        let ticker = Ticker::new();
        let done = Arc::new(AtomicUsize::new(0));
        let d = done.clone();
        ticker.run_every(Duration::from_millis(10), move || {
            d.fetch_add(1, Ordering::Relaxed) < 7
        });
        tokio::time::sleep(Duration::from_millis(35)).await;
        assert_eq!(done.load(Ordering::Relaxed), 3);
        assert_eq!(ticker.overruns(), 0);
        // The clock's task held up from its round at 30 ms to 80 ms: it runs once at 80,
        // the rounds of 40, 50, 60 and 70 missed.
        tokio::time::advance(Duration::from_millis(45)).await;
        tokio::time::sleep(Duration::from_millis(1)).await;
        assert_eq!(done.load(Ordering::Relaxed), 4);
        assert_eq!(ticker.overruns(), 4);
        // Until the work says it is done.
        tokio::time::sleep(Duration::from_millis(100)).await;
        assert_eq!(done.load(Ordering::Relaxed), 8);
        assert_eq!(ticker.registered(), 0);
    }
}
