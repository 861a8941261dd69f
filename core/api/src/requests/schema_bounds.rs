//! Numeric bounds of request fields, read from the contract's own schemas: a bound is
//! declared once, as `#[schema(minimum = …, maximum = …, exclusive_minimum = …)]` on the
//! request type, and the parser checks the value against that same declaration, so the
//! contract cannot promise more (or less) than the API accepts.
//!
//! The checks the coordinator makes against the running swarm (its geofence, the vehicle
//! models' speed limits, the minimum separation) are not here: they depend on the
//! configuration, and the contract names those fields per operation instead (see
//! [`crate::openapi`], `x-skein-swarm-checks`).

use crate::error::ApiError;
use utoipa::ToSchema;
use utoipa::openapi::RefOr;
use utoipa::openapi::schema::{Object, Schema};

/// The bounds a schema declares for one number.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Bounds {
    /// Inclusive lower bound.
    pub minimum: Option<f64>,
    /// Inclusive upper bound.
    pub maximum: Option<f64>,
    /// Exclusive lower bound.
    pub exclusive_minimum: Option<f64>,
    /// Exclusive upper bound.
    pub exclusive_maximum: Option<f64>,
}

fn number(n: &Option<utoipa::Number>) -> Option<f64> {
    #[allow(clippy::cast_precision_loss)] // schema bounds are small literals
    n.as_ref().map(|n| match *n {
        utoipa::Number::Int(i) => i as f64,
        utoipa::Number::UInt(u) => u as f64,
        utoipa::Number::Float(f) => f,
    })
}

impl Bounds {
    fn of_object(o: &Object) -> Bounds {
        Bounds {
            minimum: number(&o.minimum),
            maximum: number(&o.maximum),
            exclusive_minimum: number(&o.exclusive_minimum),
            exclusive_maximum: number(&o.exclusive_maximum),
        }
    }

    fn of_property(object: &Object, property: &str) -> Option<Bounds> {
        match object.properties.get(property)? {
            RefOr::T(Schema::Object(p)) => Some(Bounds::of_object(p)),
            _ => None,
        }
    }

    /// The bounds `T`'s schema declares for its property `property` (none declared: no
    /// bounds).
    ///
    /// # Panics
    /// If `T` has no such number property: a typo in the parser, which its tests find.
    pub fn of<T: ToSchema>(property: &str) -> Bounds {
        match T::schema() {
            RefOr::T(Schema::Object(o)) => Bounds::of_property(&o, property),
            _ => None,
        }
        .unwrap_or_else(|| panic!("{} has no number property `{property}`", T::name()))
    }

    /// The bounds an internally tagged enum's schema (`#[serde(tag = "…")]`) declares for
    /// property `property` of the variant whose tag `tag` is `variant`.
    ///
    /// # Panics
    /// If there is no such variant or property (see [`Bounds::of`]).
    pub fn of_variant<T: ToSchema>(tag: &str, variant: &str, property: &str) -> Bounds {
        let RefOr::T(Schema::OneOf(one_of)) = T::schema() else {
            panic!("{} is not an enum of objects", T::name());
        };
        one_of
            .items
            .iter()
            .find_map(|item| match item {
                RefOr::T(Schema::Object(o)) if tag_of(o, tag) == Some(variant) => {
                    Bounds::of_property(o, property)
                }
                _ => None,
            })
            .unwrap_or_else(|| panic!("{} has no variant `{variant}` with `{property}`", T::name()))
    }

    /// Only the upper bound.
    pub fn upper(self) -> Bounds {
        Bounds {
            minimum: None,
            exclusive_minimum: None,
            ..self
        }
    }

    /// Only the lower bound.
    pub fn lower(self) -> Bounds {
        Bounds {
            maximum: None,
            exclusive_maximum: None,
            ..self
        }
    }

    /// Whether `v` is within the bounds.
    pub fn contains(&self, v: f64) -> bool {
        self.minimum.is_none_or(|m| v >= m)
            && self.maximum.is_none_or(|m| v <= m)
            && self.exclusive_minimum.is_none_or(|m| v > m)
            && self.exclusive_maximum.is_none_or(|m| v < m)
    }

    /// The bounds in words, with `unit`: `above 0 m`, `at most 1000 m`, `within ±1000 m`,
    /// `within [1, 5] m`.
    pub fn describe(&self, unit: &str) -> String {
        let low = self.minimum.or(self.exclusive_minimum);
        let high = self.maximum.or(self.exclusive_maximum);
        match (low, high) {
            (None, None) => "any number".to_string(),
            (Some(l), None) if self.exclusive_minimum.is_some() => format!("above {l} {unit}"),
            (Some(l), None) => format!("at least {l} {unit}"),
            (None, Some(h)) if self.exclusive_maximum.is_some() => format!("below {h} {unit}"),
            (None, Some(h)) => format!("at most {h} {unit}"),
            (Some(l), Some(h)) if l == -h && self.minimum.is_some() && self.maximum.is_some() => {
                format!("within ±{h} {unit}")
            }
            (Some(l), Some(h)) => {
                let open = if self.exclusive_minimum.is_some() {
                    '('
                } else {
                    '['
                };
                let close = if self.exclusive_maximum.is_some() {
                    ')'
                } else {
                    ']'
                };
                format!("within {open}{l}, {h}{close} {unit}")
            }
        }
    }

    /// 400 naming `field` (`{field} must be {bounds}, got {value}`) unless `value` is within.
    ///
    /// # Errors
    /// As above.
    pub fn check(&self, field: &str, value: f64, unit: &str) -> Result<(), ApiError> {
        if self.contains(value) {
            return Ok(());
        }
        Err(ApiError::field(
            field,
            format!("{field} must be {}, got {value}", self.describe(unit)),
        ))
    }
}

/// The tag value of one variant's object schema (`{"command": {"enum": ["takeoff"]}}`).
fn tag_of<'a>(o: &'a Object, tag: &str) -> Option<&'a str> {
    match o.properties.get(tag)? {
        RefOr::T(Schema::Object(t)) => t.enum_values.as_ref()?.first()?.as_str(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(utoipa::ToSchema)]
    #[allow(dead_code)]
    struct Sample {
        #[schema(exclusive_minimum = 0.0, maximum = 1000.0)]
        spacing_m: Option<f64>,
        #[schema(minimum = -10000.0, maximum = 10000.0)]
        altitude_m: f64,
        free: f64,
    }

    #[test]
    fn bounds_are_read_from_the_schema_and_described_as_the_errors_say() {
        let spacing = Bounds::of::<Sample>("spacing_m");
        assert_eq!(spacing.exclusive_minimum, Some(0.0));
        assert_eq!(spacing.maximum, Some(1000.0));
        assert!(spacing.contains(1000.0) && !spacing.contains(0.0));
        assert_eq!(spacing.describe("m"), "within (0, 1000] m");
        assert_eq!(spacing.upper().describe("m"), "at most 1000 m");
        assert_eq!(spacing.lower().describe("m"), "above 0 m");
        let altitude = Bounds::of::<Sample>("altitude_m");
        assert_eq!(altitude.describe("m"), "within ±10000 m");
        let e = altitude.check("altitude_m", -1e20, "m").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("altitude_m"));
        assert_eq!(
            e.error,
            "altitude_m must be within ±10000 m, got -100000000000000000000"
        );
        assert_eq!(Bounds::of::<Sample>("free"), Bounds::default());
        assert!(Bounds::default().check("free", f64::MAX, "m").is_ok());
    }

    #[test]
    #[should_panic(expected = "no number property `spacing`")]
    fn a_property_the_schema_has_not_is_a_programming_error() {
        let _ = Bounds::of::<Sample>("spacing");
    }
}
