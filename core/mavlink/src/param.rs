//! Parameter values as PX4 puts them on the wire.
//!
//! PX4 announces `MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE`: an integer parameter's
//! bits are carried unchanged in the float field of `PARAM_VALUE` / `PARAM_SET`
//! (`f32::from_bits(i as u32)`), with `param_type` saying how to read them. Converting the
//! integer numerically instead (as C-cast encoders do) corrupts every value PX4 reads back.

use crate::dialect::MavParamType;
use serde::{Deserialize, Serialize};

/// A parameter value with its PX4 storage type.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// `MAV_PARAM_TYPE_INT32`.
    Int32(i32),
    /// `MAV_PARAM_TYPE_REAL32`.
    Real32(f32),
}

impl ParamValue {
    /// The `(param_value, param_type)` pair on the wire: integers bytewise.
    pub fn to_wire(self) -> (f32, MavParamType) {
        match self {
            ParamValue::Int32(i) => (f32::from_bits(i as u32), MavParamType::MAV_PARAM_TYPE_INT32),
            ParamValue::Real32(f) => (f, MavParamType::MAV_PARAM_TYPE_REAL32),
        }
    }

    /// Reads a wire pair. Smaller integer types are widened from their low bytes;
    /// `None` for types PX4 does not use (64-bit, custom).
    pub fn from_wire(raw: f32, param_type: MavParamType) -> Option<ParamValue> {
        use MavParamType as T;
        let bits = raw.to_bits();
        Some(match param_type {
            T::MAV_PARAM_TYPE_REAL32 => ParamValue::Real32(raw),
            T::MAV_PARAM_TYPE_INT32 | T::MAV_PARAM_TYPE_UINT32 => ParamValue::Int32(bits as i32),
            T::MAV_PARAM_TYPE_INT16 => ParamValue::Int32(i32::from(bits as u16 as i16)),
            T::MAV_PARAM_TYPE_UINT16 => ParamValue::Int32(i32::from(bits as u16)),
            T::MAV_PARAM_TYPE_INT8 => ParamValue::Int32(i32::from(bits as u8 as i8)),
            T::MAV_PARAM_TYPE_UINT8 => ParamValue::Int32(i32::from(bits as u8)),
            _ => return None,
        })
    }

    /// A value of the same type as `self` holding the bits of `raw` (how PX4 reads a
    /// `PARAM_SET` for a parameter whose type it already knows).
    pub fn with_wire_value(self, raw: f32) -> ParamValue {
        match self {
            ParamValue::Int32(_) => ParamValue::Int32(raw.to_bits() as i32),
            ParamValue::Real32(_) => ParamValue::Real32(raw),
        }
    }

    /// The value as a number (integers converted numerically).
    pub fn as_f64(self) -> f64 {
        match self {
            ParamValue::Int32(i) => f64::from(i),
            ParamValue::Real32(f) => f64::from(f),
        }
    }

    /// A value of the same type as `self` holding `v` (rounded for integers).
    pub fn with_f64(self, v: f64) -> ParamValue {
        match self {
            ParamValue::Int32(_) => ParamValue::Int32(v.round() as i32),
            ParamValue::Real32(_) => ParamValue::Real32(v as f32),
        }
    }
}

/// A parameter name as the 16-byte `param_id` field (NUL-padded, not terminated at 16).
pub fn param_id(name: &str) -> mavlink::types::CharArray<16> {
    name.into()
}

/// The name in a `param_id` field.
pub fn param_name(id: &mavlink::types::CharArray<16>) -> String {
    id.to_str().unwrap_or_default().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_travel_bytewise() {
        let (raw, ty) = ParamValue::Int32(1).to_wire();
        assert_eq!(ty, MavParamType::MAV_PARAM_TYPE_INT32);
        assert_eq!(raw.to_bits(), 1, "the bit pattern, not 1.0");
        assert_ne!(raw, 1.0);
        for v in [0, 1, -1, 5, 21196, i32::MIN, i32::MAX] {
            let (raw, ty) = ParamValue::Int32(v).to_wire();
            assert_eq!(ParamValue::from_wire(raw, ty), Some(ParamValue::Int32(v)));
        }
        let (raw, ty) = ParamValue::Real32(2.5).to_wire();
        assert_eq!((raw, ty), (2.5, MavParamType::MAV_PARAM_TYPE_REAL32));
        assert_eq!(
            ParamValue::from_wire(f32::from_bits(0xff), MavParamType::MAV_PARAM_TYPE_INT8),
            Some(ParamValue::Int32(-1))
        );
    }

    #[test]
    fn names_round_trip_including_16_characters() {
        assert_eq!(param_name(&param_id("COM_OF_LOSS_T")), "COM_OF_LOSS_T");
        assert_eq!(
            param_name(&param_id("ABCDEFGHIJKLMNOP")),
            "ABCDEFGHIJKLMNOP"
        );
    }
}
