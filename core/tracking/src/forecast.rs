//! Forecasts: where each track will be 5, 10 and 20 s from now, with an uncertainty.
//!
//! Three motion models extrapolate a track's estimate (swarm-frame NED, metres, m/s):
//! - **constant velocity** (CV): on along its velocity;
//! - **constant turn** (CT): on at its speed, turning at the turn rate its velocity showed
//!   over the last [`TURN_WINDOW_S`] (clamped to ±[`MAX_TURN_RATE_RAD_S`]); a coordinated
//!   turn, as a loiter flies;
//! - **mean velocity** (MV): on at the velocity averaged over the last
//!   [`MEAN_WINDOW_S`] (the displacement over the window): a weaving path's mean course,
//!   which a zig-zag's legs hide from CV and CT.
//!
//! Which model is better depends on the target and on the horizon (on a zig-zag CV wins at
//! 2 s and loses badly at 10 s), so each is chosen per track and per horizon by its
//! recent innovation: every [`SNAPSHOT_EVERY_S`] the forecaster keeps the track's state,
//! and scores each model's forecast made [`SCORED_S`] seconds ago from the state then
//! against the track's estimate now (an exponentially weighted mean of the squared
//! horizontal residual, time constant [`RESIDUAL_TAU_S`]). A horizon takes its default
//! model (constant velocity below [`LONG_HORIZON_S`], mean velocity from there on: until
//! judged, the mean course is the safer long guess, and on a straight path the two agree)
//! unless another has beaten it by 20 % at the longest scored horizon not beyond it, once
//! that horizon is as long as the forecast's (or [`LONG_HORIZON_S`]).
//!
//! The uncertainty (one σ, horizontal, metres) is the filter's position variance plus its
//! velocity variance grown over the horizon, plus the chosen model's recent mean squared
//! residual scaled to the horizon: it is as wide as the model has lately been wrong.

use nalgebra::Vector3;
use skein_protocol::tracks::{ForecastPoint, MotionModel, NedJson, TrackStatus, TrackView};
use std::collections::{BTreeMap, VecDeque};

/// The horizons every track and swarm is forecast at, seconds.
pub const HORIZONS_S: [f64; 3] = [5.0, 10.0, 20.0];
/// The horizons each model's residuals are scored at, seconds.
pub const SCORED_S: [f64; 3] = [2.0, 5.0, 10.0];
/// How often a track's state is kept for scoring, seconds.
pub const SNAPSHOT_EVERY_S: f64 = 0.5;
/// How long states are kept, seconds (the longest scored horizon and the mean window).
pub const HISTORY_S: f64 = 16.0;
/// The mean-velocity model's window, seconds (it needs a third of it at least).
pub const MEAN_WINDOW_S: f64 = 12.0;
/// The window the turn rate is measured over, seconds.
pub const TURN_WINDOW_S: f64 = 2.0;
/// Largest turn rate the CT model uses, rad/s.
pub const MAX_TURN_RATE_RAD_S: f64 = 0.6;
/// Time constant of the residual scores, seconds.
pub const RESIDUAL_TAU_S: f64 = 8.0;
/// Another model replaces the default only when its score is below this fraction of the
/// default's.
const SWITCH_RATIO: f64 = 0.8;
/// From this horizon on the default model is mean velocity, seconds.
pub const LONG_HORIZON_S: f64 = 10.0;
/// Scores needed before a horizon's scores are used.
const MIN_SCORES: u32 = 3;

const MODELS: [MotionModel; 3] = [
    MotionModel::ConstantVelocity,
    MotionModel::ConstantTurn,
    MotionModel::MeanVelocity,
];

/// What the models extrapolate from: a track's state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionState {
    /// Position, swarm-frame NED, metres.
    pub position: Vector3<f64>,
    /// Velocity, NED, m/s.
    pub velocity: Vector3<f64>,
    /// Turn rate of the horizontal velocity, rad/s, positive clockwise seen from above.
    pub turn_rad_s: f64,
    /// Velocity averaged over the last [`MEAN_WINDOW_S`], NED, m/s.
    pub mean_velocity: Vector3<f64>,
}

/// Where `model` puts a target in state `s` after `h_s` seconds.
pub fn extrapolate(model: MotionModel, s: &MotionState, h_s: f64) -> Vector3<f64> {
    match model {
        MotionModel::ConstantVelocity => s.position + s.velocity * h_s,
        MotionModel::MeanVelocity => s.position + s.mean_velocity * h_s,
        MotionModel::ConstantTurn => {
            let w = s.turn_rad_s;
            let speed = s.velocity.x.hypot(s.velocity.y);
            if w.abs() < 1e-3 || speed < 1e-6 {
                return s.position + s.velocity * h_s;
            }
            // Heading ψ clockwise from north: v = speed (cos ψ, sin ψ).
            let psi = s.velocity.y.atan2(s.velocity.x);
            let n = speed / w * ((psi + w * h_s).sin() - psi.sin());
            let e = speed / w * (psi.cos() - (psi + w * h_s).cos());
            s.position + Vector3::new(n, e, s.velocity.z * h_s)
        }
    }
}

/// The signed angle from horizontal vector `a` to `b`, radians, positive clockwise seen
/// from above (north towards east).
fn turn_angle(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    (a.x * b.y - a.y * b.x).atan2(a.x * b.x + a.y * b.y)
}

fn horizontal(v: &Vector3<f64>) -> f64 {
    v.x.hypot(v.y)
}

#[derive(Debug, Clone)]
struct Snapshot {
    t_s: f64,
    state: MotionState,
}

/// Running residual score of one model at one scored horizon.
#[derive(Debug, Clone, Copy, Default)]
struct Score {
    mean_sq_m2: f64,
    count: u32,
}

/// One track's history and model scores.
#[derive(Debug, Clone, Default)]
pub struct TrackForecaster {
    history: VecDeque<Snapshot>,
    /// `scores[h][m]`: scored horizon `SCORED_S[h]`, model `MODELS[m]`.
    scores: [[Score; 3]; 3],
}

impl TrackForecaster {
    /// The state of a track estimated at `position`, `velocity` at `t_s`, with its turn
    /// rate and mean velocity from the history.
    fn state_now(&self, t_s: f64, position: Vector3<f64>, velocity: Vector3<f64>) -> MotionState {
        let turn_rad_s = self
            .history
            .iter()
            .find(|s| t_s - s.t_s <= TURN_WINDOW_S + 1e-6)
            .filter(|s| t_s - s.t_s >= 0.5 * TURN_WINDOW_S)
            .filter(|s| horizontal(&s.state.velocity) > 1.0 && horizontal(&velocity) > 1.0)
            .map(|s| turn_angle(&s.state.velocity, &velocity) / (t_s - s.t_s))
            .unwrap_or(0.0)
            .clamp(-MAX_TURN_RATE_RAD_S, MAX_TURN_RATE_RAD_S);
        let mean_velocity = self
            .history
            .iter()
            .find(|s| t_s - s.t_s <= MEAN_WINDOW_S + 1e-6)
            .filter(|s| t_s - s.t_s >= MEAN_WINDOW_S / 3.0)
            .map_or(velocity, |s| (position - s.state.position) / (t_s - s.t_s));
        MotionState {
            position,
            velocity,
            turn_rad_s,
            mean_velocity,
        }
    }

    /// Keeps the state at `t_s` (every [`SNAPSHOT_EVERY_S`]) and scores the models'
    /// forecasts made [`SCORED_S`] ago against it.
    pub fn observe(&mut self, t_s: f64, position: Vector3<f64>, velocity: Vector3<f64>) {
        if self
            .history
            .back()
            .is_some_and(|s| t_s - s.t_s < SNAPSHOT_EVERY_S - 1e-6)
        {
            return;
        }
        let state = self.state_now(t_s, position, velocity);
        let alpha = 1.0 - (-SNAPSHOT_EVERY_S / RESIDUAL_TAU_S).exp();
        for (hi, h) in SCORED_S.iter().enumerate() {
            let Some(then) = self
                .history
                .iter()
                .find(|s| (t_s - s.t_s - h).abs() <= SNAPSHOT_EVERY_S / 2.0 + 1e-6)
            else {
                continue;
            };
            let dt = t_s - then.t_s;
            for (mi, m) in MODELS.iter().enumerate() {
                let e = extrapolate(*m, &then.state, dt) - position;
                let e2 = e.x * e.x + e.y * e.y;
                let sc = &mut self.scores[hi][mi];
                sc.mean_sq_m2 = if sc.count == 0 {
                    e2
                } else {
                    sc.mean_sq_m2 + alpha * (e2 - sc.mean_sq_m2)
                };
                sc.count += 1;
            }
        }
        self.history.push_back(Snapshot { t_s, state });
        while self
            .history
            .front()
            .is_some_and(|s| t_s - s.t_s > HISTORY_S)
        {
            self.history.pop_front();
        }
    }

    /// The model for horizon `h_s` and the index of the scored horizon whose residuals size
    /// its σ (see the module docs: the default model, constant velocity below
    /// [`LONG_HORIZON_S`] and mean velocity from there on, unless another has beaten it
    /// by 20 % at a scored horizon as long as `h_s`, or [`LONG_HORIZON_S`]).
    pub fn choose(&self, h_s: f64) -> (MotionModel, Option<usize>) {
        let judged = (0..SCORED_S.len())
            .rev()
            .filter(|&i| self.scores[i][0].count >= MIN_SCORES)
            .find(|&i| SCORED_S[i] <= h_s + 1e-9)
            .or_else(|| (0..SCORED_S.len()).find(|&i| self.scores[i][0].count >= MIN_SCORES));
        let default = if h_s >= LONG_HORIZON_S - 1e-9 { 2 } else { 0 };
        let Some(hi) = judged else {
            return (MODELS[default], None);
        };
        if SCORED_S[hi] < h_s.min(LONG_HORIZON_S) - 1e-9 {
            return (MODELS[default], Some(hi));
        }
        let s = &self.scores[hi];
        let (best, _) = (0..MODELS.len())
            .filter(|m| *m != default)
            .map(|m| (m, s[m].mean_sq_m2))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((default, f64::INFINITY));
        let m = if s[best].mean_sq_m2 < SWITCH_RATIO * s[default].mean_sq_m2 {
            best
        } else {
            default
        };
        (MODELS[m], Some(hi))
    }

    /// The forecast of `track` at every horizon of [`HORIZONS_S`], from the state at `t_s`.
    pub fn forecast(&self, t_s: f64, track: &TrackView) -> Vec<ForecastPoint> {
        let p = &track.position;
        let v = &track.velocity;
        let c = &track.covariance_ne_m2;
        self.forecast_from(
            t_s,
            Vector3::new(p.north_m, p.east_m, p.down_m),
            Vector3::new(v.north_m_s, v.east_m_s, v.down_m_s),
            (c[0][0] + c[1][1]).max(0.0),
            track.velocity_sigma_m_s,
        )
    }

    /// True when some horizon's residuals have been scored (the models have been judged).
    pub fn judged(&self) -> bool {
        self.choose(HORIZONS_S[0]).1.is_some()
    }

    /// The forecast of a target at `position` moving at `velocity` at `t_s`, with a
    /// horizontal position variance (m²) and a velocity σ (m/s).
    pub fn forecast_from(
        &self,
        t_s: f64,
        position: Vector3<f64>,
        velocity: Vector3<f64>,
        position_var: f64,
        velocity_sigma_m_s: f64,
    ) -> Vec<ForecastPoint> {
        let state = self.state_now(t_s, position, velocity);
        HORIZONS_S
            .iter()
            .map(|&h| {
                let (model, judged) = self.choose(h);
                let mi = MODELS.iter().position(|m| *m == model).unwrap_or(0);
                let residual_var = judged.map_or(0.0, |hi| {
                    self.scores[hi][mi].mean_sq_m2 * (h / SCORED_S[hi]).powi(2)
                });
                let grown = (velocity_sigma_m_s * h).powi(2);
                let q = extrapolate(model, &state, h);
                ForecastPoint {
                    horizon_s: h,
                    position: NedJson {
                        north_m: q.x,
                        east_m: q.y,
                        down_m: q.z,
                    },
                    sigma_m: (position_var + grown + residual_var).sqrt(),
                    model,
                }
            })
            .collect()
    }
}

/// The forecasters of every track, by id.
#[derive(Debug, Default)]
pub struct Forecaster {
    tracks: BTreeMap<String, TrackForecaster>,
}

impl Forecaster {
    /// Feeds the tracks as of `now_us` (wall-clock µs) into their histories (confirmed
    /// tracks only: a lost one's estimate is a prediction already) and fills in each
    /// track's `forecast`. Tracks that are gone are forgotten.
    pub fn update(&mut self, now_us: u64, tracks: &mut [TrackView]) {
        let t_s = now_us as f64 / 1e6;
        self.tracks
            .retain(|id, _| tracks.iter().any(|t| t.id == *id));
        for t in tracks.iter_mut() {
            let f = self.tracks.entry(t.id.clone()).or_default();
            if t.status == TrackStatus::Confirmed {
                let p = &t.position;
                let v = &t.velocity;
                f.observe(
                    t_s,
                    Vector3::new(p.north_m, p.east_m, p.down_m),
                    Vector3::new(v.north_m_s, v.east_m_s, v.down_m_s),
                );
            }
            t.forecast = f.forecast(t_s, t);
        }
    }
}

/// The forecast of a group (a swarm's centroid): at each horizon the mean of the
/// members' predicted positions, σ the root mean square of theirs (their errors are
/// correlated: a swarm manoeuvres together), the model most of them use.
pub fn mean_forecast(members: &[&[ForecastPoint]]) -> Vec<ForecastPoint> {
    HORIZONS_S
        .iter()
        .filter_map(|&h| {
            let points: Vec<&ForecastPoint> = members
                .iter()
                .filter_map(|f| f.iter().find(|p| (p.horizon_s - h).abs() < 1e-9))
                .collect();
            if points.is_empty() {
                return None;
            }
            let n = points.len() as f64;
            let sum = |f: &dyn Fn(&ForecastPoint) -> f64| points.iter().map(|p| f(p)).sum::<f64>();
            // Ties go to the first model (constant velocity).
            let model = MODELS
                .iter()
                .rev()
                .copied()
                .max_by_key(|m| points.iter().filter(|p| p.model == *m).count())
                .unwrap_or(MotionModel::ConstantVelocity);
            Some(ForecastPoint {
                horizon_s: h,
                position: NedJson {
                    north_m: sum(&|p| p.position.north_m) / n,
                    east_m: sum(&|p| p.position.east_m) / n,
                    down_m: sum(&|p| p.position.down_m) / n,
                },
                sigma_m: (sum(&|p| p.sigma_m * p.sigma_m) / n).sqrt(),
                model,
            })
        })
        .collect()
}
