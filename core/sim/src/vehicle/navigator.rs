//! Navigator (PX4 `navigator` and the auto flight tasks): take-off, land, RTL, hold and
//! reposition, and the choice of what the position controller tracks in each mode
//! ([`Goal`]).

#![allow(deprecated)]

use super::*;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RtlPhase {
    Climb,
    Return,
    Land,
}

impl Vehicle {
    pub(super) fn braking_point(&self) -> Ned {
        let here = self.nav_pos();
        if self.landed {
            return here;
        }
        let acc_h = self.params.get(Param::MPC_ACC_HOR).max(0.5);
        let vh = self.vel.horizontal_norm();
        let k = vh / (2.0 * acc_h);
        let vz = self.vel.down_m;
        let dz = vz * vz.abs() / (2.0 * 3.0);
        // The ground, where the navigator sees it (0 without the GNSS error).
        let ground = here.down_m - self.pos.down_m;
        Ned::new(
            here.north_m + self.vel.north_m * k,
            here.east_m + self.vel.east_m * k,
            (here.down_m + dz).min(ground),
        )
    }

    pub(super) fn enter_mode(&mut self, mode: Px4Mode) {
        let here = self.nav_pos();
        self.mode = mode;
        self.traj_valid = false;
        match mode {
            Px4Mode::Takeoff => {
                self.takeoff_z = self.home_local.down_m - self.params.get(Param::MIS_TAKEOFF_ALT);
                self.hold_pos = here;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Land | Px4Mode::Precland => {
                self.land_xy = (here.north_m, here.east_m);
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Rtl => {
                self.rtl_phase = RtlPhase::Climb;
                let return_z = self.home_local.down_m - self.params.get(Param::RTL_RETURN_ALT);
                self.rtl_z = return_z.min(here.down_m);
                self.rtl_start = here;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            Px4Mode::Offboard => {
                self.hold_pos = here;
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
            }
            _ => {
                self.hold_pos = self.braking_point();
                self.hold_yaw = YawGoal::Heading(self.yaw_rad);
                self.auto_speed_m_s = None;
            }
        }
    }

    pub(super) fn takeoff(&mut self, now: Instant, alt_amsl_m: f32, out: &mut Outbox) -> MavResult {
        if let Some(reason) = self.mode_denied_reason(now, Px4Mode::Takeoff) {
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
            return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
        }
        self.enter_mode(Px4Mode::Takeoff);
        self.failsafe = false;
        if alt_amsl_m.is_finite() {
            self.takeoff_z = -(f64::from(alt_amsl_m) - self.origin.origin.alt_amsl_m);
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn reposition(
        &mut self,
        now: Instant,
        cmd: &Command,
        out: &mut Outbox,
    ) -> MavResult {
        if let Some(reason) = self.mode_denied_reason(now, Px4Mode::Hold) {
            self.statustext(now, MavSeverity::MAV_SEVERITY_CRITICAL, reason, out);
            return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
        }
        let p = cmd.params;
        let here = self.nav_pos();
        let current = self.origin.to_geo(here);
        let (lat, lon, alt) = match cmd.int_xy {
            Some((frame, x, y)) => {
                let alt = match frame {
                    MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => f64::from(p[6]),
                    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
                        self.home.alt_amsl_m + f64::from(p[6])
                    }
                    _ => return MavResult::MAV_RESULT_UNSUPPORTED,
                };
                let unset = |v: i32| v == i32::MAX || (x == 0 && y == 0);
                (
                    if unset(x) {
                        current.lat_deg
                    } else {
                        f64::from(x) * 1e-7
                    },
                    if unset(y) {
                        current.lon_deg
                    } else {
                        f64::from(y) * 1e-7
                    },
                    alt,
                )
            }
            None => (f64::from(p[4]), f64::from(p[5]), f64::from(p[6])),
        };
        let target = GeoPoint::new(
            if lat.is_finite() {
                lat
            } else {
                current.lat_deg
            },
            if lon.is_finite() {
                lon
            } else {
                current.lon_deg
            },
            if alt.is_finite() {
                alt
            } else {
                current.alt_amsl_m
            },
        );
        let mut local = self.origin.to_ned(&target);
        local.down_m = local.down_m.min(0.0);
        self.enter_mode(Px4Mode::Hold);
        self.failsafe = false;
        if self.armed && !self.landed {
            self.hold_pos = local;
            self.auto_speed_m_s = (p[0] > 0.0 && p[0].is_finite()).then_some(f64::from(p[0]));
            let to = local - here;
            self.hold_yaw = if p[3].is_finite() {
                YawGoal::Heading(f64::from(p[3]).to_radians())
            } else if to.horizontal_norm() > 2.0 {
                YawGoal::Heading(to.east_m.atan2(to.north_m))
            } else {
                YawGoal::Heading(self.yaw_rad)
            };
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn update_navigation(&mut self, now: Instant, out: &mut Outbox) {
        if !self.armed || self.landed {
            return;
        }
        let here = self.nav_pos();
        match self.mode {
            Px4Mode::Takeoff
                if (here.down_m - self.takeoff_z).abs() < 0.2 || here.down_m < self.takeoff_z =>
            {
                let target = Ned::new(self.hold_pos.north_m, self.hold_pos.east_m, self.takeoff_z);
                let yaw = self.hold_yaw;
                self.enter_mode(Px4Mode::Hold);
                self.hold_pos = target;
                self.hold_yaw = yaw;
                self.statustext(now, MavSeverity::MAV_SEVERITY_INFO, "Takeoff complete", out);
            }
            Px4Mode::Rtl => match self.rtl_phase {
                RtlPhase::Climb => {
                    if here.down_m <= self.rtl_z + 0.5 {
                        self.rtl_phase = RtlPhase::Return;
                        let to = self.home_local - here;
                        if to.horizontal_norm() > 2.0 {
                            self.hold_yaw = YawGoal::Heading(to.east_m.atan2(to.north_m));
                        }
                    }
                }
                RtlPhase::Return => {
                    let to = self.home_local - here;
                    if to.horizontal_norm() < 1.0 && self.vel.horizontal_norm() < 1.0 {
                        self.rtl_phase = RtlPhase::Land;
                        self.land_xy = (self.home_local.north_m, self.home_local.east_m);
                        self.hold_yaw = YawGoal::Heading(self.home_yaw_rad);
                    }
                }
                RtlPhase::Land => {}
            },
            _ => {}
        }
    }

    /// Descent speed PX4 uses when landing at `height_m` above home.
    pub(super) fn land_speed_m_s(&self, height_m: f64) -> f64 {
        let slow = self.params.get(Param::MPC_LAND_SPEED);
        let fast = self.params.get(Param::MPC_Z_V_AUTO_DN).max(slow);
        let alt1 = self.params.get(Param::MPC_LAND_ALT1);
        let alt2 = self.params.get(Param::MPC_LAND_ALT2).min(alt1);
        let alt3 = self.params.get(Param::MPC_LAND_ALT3).min(alt2);
        if height_m <= alt3 {
            return slow.min(self.params.get(Param::MPC_LAND_CRWL).max(0.05));
        }
        if height_m >= alt1 {
            fast
        } else if height_m <= alt2 || alt1 <= alt2 {
            slow
        } else {
            slow + (fast - slow) * (height_m - alt2) / (alt1 - alt2)
        }
    }

    pub(super) fn offboard_wants_takeoff(&self) -> bool {
        let Some(sp) = self.setpoint else {
            return false;
        };
        sp.pos[2].is_some_and(|z| z < self.nav_pos().down_m - TAKEOFF_DETECT_M)
            || sp.vel[2].is_some_and(|vz| vz < -0.05)
    }

    /// What the vehicle flies now: idle or falling when disarmed, else the goal of its
    /// mode (auto modes hold, take off, land or return; offboard follows the setpoint).
    pub(super) fn compute_goal(&self) -> Goal {
        if !self.armed {
            return if self.landed {
                Goal::Idle
            } else {
                Goal::FreeFall
            };
        }
        let wants_takeoff = match self.mode {
            Px4Mode::Takeoff => self.takeoff_z < self.nav_pos().down_m - TAKEOFF_DETECT_M,
            Px4Mode::Offboard => self.offboard_wants_takeoff(),
            _ => false,
        };
        if self.landed && !wants_takeoff {
            return Goal::Idle;
        }
        let limits = self.auto_limits();
        match self.mode {
            Px4Mode::Takeoff => Goal::Track(Track {
                pos: [
                    Some(self.hold_pos.north_m),
                    Some(self.hold_pos.east_m),
                    Some(self.takeoff_z),
                ],
                up_max_m_s: self.params.get(Param::MPC_TKO_SPEED),
                ..limits.track(self.hold_yaw)
            }),
            Px4Mode::Land | Px4Mode::Precland => self.land_goal(&limits),
            Px4Mode::Rtl => match self.rtl_phase {
                RtlPhase::Climb => limits.hold(
                    Ned::new(self.rtl_start.north_m, self.rtl_start.east_m, self.rtl_z),
                    self.hold_yaw,
                ),
                RtlPhase::Return => limits.hold(
                    Ned::new(self.home_local.north_m, self.home_local.east_m, self.rtl_z),
                    self.hold_yaw,
                ),
                RtlPhase::Land => self.land_goal(&limits),
            },
            Px4Mode::Offboard => self.offboard_goal(),
            _ => limits.hold(self.hold_pos, self.hold_yaw),
        }
    }

    /// The limits of the auto modes (PX4's `MPC_XY_CRUISE`, or a DO_CHANGE_SPEED, under
    /// `MPC_XY_VEL_MAX`; `MPC_Z_V_AUTO_*`, `MPC_YAWRAUTO_MAX`).
    fn auto_limits(&self) -> AutoLimits {
        let p = &self.params;
        let cruise = p
            .get(Param::MPC_XY_CRUISE)
            .min(p.get(Param::MPC_XY_VEL_MAX));
        AutoLimits {
            xy_m_s: self
                .auto_speed_m_s
                .unwrap_or(cruise)
                .min(p.get(Param::MPC_XY_VEL_MAX)),
            up_m_s: p.get(Param::MPC_Z_V_AUTO_UP),
            down_m_s: p.get(Param::MPC_Z_V_AUTO_DN),
            yaw_rate_rad_s: p.get(Param::MPC_YAWRAUTO_MAX).to_radians(),
        }
    }

    /// Landing where the land started: down at PX4's landing speed for the height.
    fn land_goal(&self, limits: &AutoLimits) -> Goal {
        Goal::Track(Track {
            pos: [Some(self.land_xy.0), Some(self.land_xy.1), None],
            vel: [
                None,
                None,
                Some(self.land_speed_m_s(self.height_above_home_m())),
            ],
            down_max_m_s: limits.down_m_s.max(self.params.get(Param::MPC_LAND_SPEED)),
            ..limits.track(self.hold_yaw)
        })
    }

    /// Offboard: the last setpoint as given (a hold where offboard began before the
    /// first), raw, within the vehicle's maximum speeds.
    fn offboard_goal(&self) -> Goal {
        let p = &self.params;
        let sp = self.setpoint.unwrap_or(Setpoint {
            pos: [
                Some(self.hold_pos.north_m),
                Some(self.hold_pos.east_m),
                Some(self.hold_pos.down_m),
            ],
            ..Setpoint::default()
        });
        let yaw = match (sp.yaw_rad, sp.yaw_rate_rad_s) {
            (Some(y), _) => YawGoal::Heading(y),
            (None, Some(r)) => YawGoal::Rate(r),
            (None, None) => YawGoal::Rate(0.0),
        };
        Goal::Track(Track {
            pos: sp.pos,
            vel: sp.vel,
            acc: sp.acc,
            xy_max_m_s: p.get(Param::MPC_XY_VEL_MAX),
            up_max_m_s: p.get(Param::MPC_Z_VEL_MAX_UP),
            down_max_m_s: p.get(Param::MPC_Z_VEL_MAX_DN),
            yaw,
            yaw_rate_max_rad_s: p.get(Param::MC_YAWRATE_MAX).to_radians(),
            smooth: false,
        })
    }
}

/// The speed limits of PX4's auto modes.
struct AutoLimits {
    /// Horizontal, m/s.
    xy_m_s: f64,
    /// Climbing, m/s.
    up_m_s: f64,
    /// Descending, m/s.
    down_m_s: f64,
    /// Yaw rate, rad/s.
    yaw_rate_rad_s: f64,
}

impl AutoLimits {
    /// A smooth track within these limits, towards nothing yet (`pos` to be set).
    fn track(&self, yaw: YawGoal) -> Track {
        Track {
            pos: [None; 3],
            vel: [None; 3],
            acc: [None; 3],
            xy_max_m_s: self.xy_m_s,
            up_max_m_s: self.up_m_s,
            down_max_m_s: self.down_m_s,
            yaw,
            yaw_rate_max_rad_s: self.yaw_rate_rad_s,
            smooth: true,
        }
    }

    /// Holding `pos` with heading goal `yaw`.
    fn hold(&self, pos: Ned, yaw: YawGoal) -> Goal {
        Goal::Track(Track {
            pos: [Some(pos.north_m), Some(pos.east_m), Some(pos.down_m)],
            ..self.track(yaw)
        })
    }
}
