//! The PX4 parameters the simulator implements, with PX4 v1.16 defaults, and PX4's
//! *bytewise* wire encoding of integer parameters (the int32 bit pattern carried in the
//! float field of `PARAM_VALUE` / `PARAM_SET`, type `MAV_PARAM_TYPE_INT32`).

pub use skein_mavlink::param::ParamValue;

macro_rules! params {
    ($( $var:ident = $name:literal : $kind:ident($default:expr) ),* $(,)?) => {
        /// Every parameter the simulator knows, in PX4's (alphabetical) listing order.
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[allow(non_camel_case_types)]
        pub enum Param { $( #[doc = concat!("PX4 parameter `", $name, "`.")] $var ),* }

        /// `(name, default)` in [`Param`] order.
        const DEFS: &[(&str, ParamValue)] = &[ $( ($name, ParamValue::$kind($default)) ),* ];
    };
}

params! {
    BAT1_CAPACITY = "BAT1_CAPACITY": Real32(5000.0),
    BAT1_N_CELLS = "BAT1_N_CELLS": Int32(4),
    BAT1_V_CHARGED = "BAT1_V_CHARGED": Real32(4.05),
    BAT1_V_EMPTY = "BAT1_V_EMPTY": Real32(3.6),
    COM_ARM_ODID = "COM_ARM_ODID": Int32(0),
    COM_DISARM_LAND = "COM_DISARM_LAND": Real32(2.0),
    COM_DISARM_PRFLT = "COM_DISARM_PRFLT": Real32(10.0),
    COM_DL_LOSS_T = "COM_DL_LOSS_T": Int32(10),
    COM_OBL_RC_ACT = "COM_OBL_RC_ACT": Int32(0),
    COM_OF_LOSS_T = "COM_OF_LOSS_T": Real32(1.0),
    COM_RC_IN_MODE = "COM_RC_IN_MODE": Int32(3),
    GF_ACTION = "GF_ACTION": Int32(2),
    GF_MAX_HOR_DIST = "GF_MAX_HOR_DIST": Real32(0.0),
    GF_MAX_VER_DIST = "GF_MAX_VER_DIST": Real32(0.0),
    MAV_SIGN_CFG = "MAV_SIGN_CFG": Int32(0),
    MAV_SYS_ID = "MAV_SYS_ID": Int32(1),
    MC_YAWRATE_MAX = "MC_YAWRATE_MAX": Real32(200.0),
    MC_YAW_P = "MC_YAW_P": Real32(2.8),
    MIS_TAKEOFF_ALT = "MIS_TAKEOFF_ALT": Real32(2.5),
    MPC_ACC_DOWN_MAX = "MPC_ACC_DOWN_MAX": Real32(3.0),
    MPC_ACC_HOR = "MPC_ACC_HOR": Real32(3.0),
    MPC_ACC_HOR_MAX = "MPC_ACC_HOR_MAX": Real32(5.0),
    MPC_ACC_UP_MAX = "MPC_ACC_UP_MAX": Real32(4.0),
    MPC_LAND_ALT1 = "MPC_LAND_ALT1": Real32(10.0),
    MPC_LAND_ALT2 = "MPC_LAND_ALT2": Real32(5.0),
    MPC_LAND_ALT3 = "MPC_LAND_ALT3": Real32(1.0),
    MPC_LAND_CRWL = "MPC_LAND_CRWL": Real32(0.3),
    MPC_LAND_SPEED = "MPC_LAND_SPEED": Real32(0.7),
    MPC_THR_HOVER = "MPC_THR_HOVER": Real32(0.5),
    MPC_THR_MAX = "MPC_THR_MAX": Real32(1.0),
    MPC_THR_MIN = "MPC_THR_MIN": Real32(0.12),
    MPC_THR_XY_MARG = "MPC_THR_XY_MARG": Real32(0.3),
    MPC_TILTMAX_AIR = "MPC_TILTMAX_AIR": Real32(45.0),
    MPC_TKO_SPEED = "MPC_TKO_SPEED": Real32(1.5),
    MPC_XY_CRUISE = "MPC_XY_CRUISE": Real32(5.0),
    MPC_XY_P = "MPC_XY_P": Real32(0.95),
    MPC_XY_VEL_D_ACC = "MPC_XY_VEL_D_ACC": Real32(0.2),
    MPC_XY_VEL_I_ACC = "MPC_XY_VEL_I_ACC": Real32(0.4),
    MPC_XY_VEL_MAX = "MPC_XY_VEL_MAX": Real32(12.0),
    MPC_XY_VEL_P_ACC = "MPC_XY_VEL_P_ACC": Real32(1.8),
    MPC_YAWRAUTO_MAX = "MPC_YAWRAUTO_MAX": Real32(45.0),
    MPC_Z_P = "MPC_Z_P": Real32(1.0),
    MPC_Z_VEL_D_ACC = "MPC_Z_VEL_D_ACC": Real32(0.0),
    MPC_Z_VEL_I_ACC = "MPC_Z_VEL_I_ACC": Real32(2.0),
    MPC_Z_VEL_MAX_DN = "MPC_Z_VEL_MAX_DN": Real32(1.5),
    MPC_Z_VEL_MAX_UP = "MPC_Z_VEL_MAX_UP": Real32(3.0),
    MPC_Z_VEL_P_ACC = "MPC_Z_VEL_P_ACC": Real32(4.0),
    MPC_Z_V_AUTO_DN = "MPC_Z_V_AUTO_DN": Real32(1.5),
    MPC_Z_V_AUTO_UP = "MPC_Z_V_AUTO_UP": Real32(3.0),
    NAV_DLL_ACT = "NAV_DLL_ACT": Int32(0),
    NAV_RCL_ACT = "NAV_RCL_ACT": Int32(2),
    RTL_DESCEND_ALT = "RTL_DESCEND_ALT": Real32(30.0),
    RTL_RETURN_ALT = "RTL_RETURN_ALT": Real32(30.0),
    SIH_KDV = "SIH_KDV": Real32(1.0),
    SIH_MASS = "SIH_MASS": Real32(1.0),
    SYSID_THISMAV = "SYSID_THISMAV": Int32(1),
}

impl Param {
    /// The PX4 name (`"MIS_TAKEOFF_ALT"`).
    pub fn name(self) -> &'static str {
        DEFS[self as usize].0
    }

    /// PX4's default value.
    pub fn default_value(self) -> ParamValue {
        DEFS[self as usize].1
    }
}

/// Number of parameters (`PARAM_VALUE.param_count`).
pub const PARAM_COUNT: usize = DEFS.len();

/// One vehicle's parameter set.
#[derive(Debug, Clone)]
pub struct Params {
    values: [ParamValue; PARAM_COUNT],
}

impl Params {
    /// PX4 defaults for system `sysid` (`MAV_SYS_ID`, `SYSID_THISMAV`), then `overrides`
    /// by name (unknown names are ignored and returned).
    pub fn new(sysid: u8, overrides: &[(String, f64)]) -> (Params, Vec<String>) {
        let mut values = [ParamValue::Int32(0); PARAM_COUNT];
        for (slot, (_, default)) in values.iter_mut().zip(DEFS) {
            *slot = *default;
        }
        let mut p = Params { values };
        p.values[Param::MAV_SYS_ID as usize] = ParamValue::Int32(i32::from(sysid));
        p.values[Param::SYSID_THISMAV as usize] = ParamValue::Int32(i32::from(sysid));
        let mut unknown = Vec::new();
        for (name, v) in overrides {
            match Self::index_of(name) {
                Some(i) => p.values[i] = p.values[i].with_f64(*v),
                None => unknown.push(name.clone()),
            }
        }
        (p, unknown)
    }

    /// Index of a parameter by name (as in `PARAM_REQUEST_READ.param_id`).
    pub fn index_of(name: &str) -> Option<usize> {
        DEFS.iter().position(|(n, _)| *n == name)
    }

    /// Name of the parameter at `index`.
    pub fn name_at(index: usize) -> Option<&'static str> {
        DEFS.get(index).map(|(n, _)| *n)
    }

    /// Value at `index`.
    pub fn value_at(&self, index: usize) -> Option<ParamValue> {
        self.values.get(index).copied()
    }

    /// Replaces the value at `index`.
    pub fn set_at(&mut self, index: usize, value: ParamValue) {
        if let Some(v) = self.values.get_mut(index) {
            *v = value;
        }
    }

    /// A parameter as a float (the form the flight logic uses).
    pub fn get(&self, p: Param) -> f64 {
        self.values[p as usize].as_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skein_mavlink::dialect::MavParamType;

    #[test]
    fn table_is_sorted_like_px4_lists_it_and_enum_matches() {
        for w in DEFS.windows(2) {
            assert!(w[0].0 < w[1].0, "{} before {}", w[0].0, w[1].0);
        }
        assert_eq!(Param::MIS_TAKEOFF_ALT.name(), "MIS_TAKEOFF_ALT");
        assert_eq!(Param::SYSID_THISMAV.name(), "SYSID_THISMAV");
        for (name, _) in DEFS {
            assert!(name.len() <= 16, "{name} does not fit param_id");
        }
    }

    #[test]
    fn bytewise_integer_encoding() {
        let (raw, ty) = ParamValue::Int32(3).to_wire();
        assert_eq!(ty, MavParamType::MAV_PARAM_TYPE_INT32);
        assert_eq!(raw.to_bits(), 3);
        assert_eq!(
            ParamValue::Int32(0).with_wire_value(f32::from_bits(5)),
            ParamValue::Int32(5)
        );
        assert_eq!(
            ParamValue::Real32(0.0).with_wire_value(2.5),
            ParamValue::Real32(2.5)
        );
    }

    #[test]
    fn overrides_and_sysid() {
        let (p, unknown) = Params::new(7, &[("MIS_TAKEOFF_ALT".into(), 5.0), ("NOPE".into(), 1.0)]);
        assert_eq!(p.get(Param::MIS_TAKEOFF_ALT), 5.0);
        assert_eq!(p.get(Param::MAV_SYS_ID), 7.0);
        assert_eq!(unknown, vec!["NOPE".to_string()]);
    }
}
