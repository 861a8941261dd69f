//! Where a payload slot's driver comes from, decided from the providers loaded now: a
//! slot whose kind (from its named plugin, if any) no provider offers waits for a plugin
//! instead of failing, and a run-time attach is checked the same way. Pure functions,
//! so the decisions are tested without actors.

use skein_payload::{PayloadSpec, ProviderInfo};

/// What to do with a slot now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Placement {
    /// A loaded provider offers its kind: create the driver (named: the provider).
    Create(String),
    /// No loaded provider does: the slot waits (status `waiting_for_plugin`); the text
    /// names the kind (and the plugin, when the slot names one).
    Wait(String),
}

/// The first provider that serves `spec` (its named plugin, or any offering its kind), in
/// the order the factories are asked.
pub fn provider_for<'a>(
    spec: &PayloadSpec,
    providers: &'a [ProviderInfo],
) -> Option<&'a ProviderInfo> {
    providers.iter().find(|p| {
        p.kinds.contains(&spec.kind) && spec.plugin.as_ref().is_none_or(|name| *name == p.name)
    })
}

/// Create `spec`'s driver now, or wait for a plugin.
pub fn placement(spec: &PayloadSpec, providers: &[ProviderInfo]) -> Placement {
    match provider_for(spec, providers) {
        Some(p) => Placement::Create(p.name.clone()),
        None => Placement::Wait(format!(
            "waiting for a plugin providing payload kind `{}`{}",
            spec.kind,
            spec.plugin
                .as_ref()
                .map(|p| format!(" (plugin `{p}`)"))
                .unwrap_or_default()
        )),
    }
}

/// Why an attach is refused: the request field at fault and the reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AttachRefusal {
    /// `"slot"`, `"kind"` or `"plugin"`.
    pub field: &'static str,
    /// What is wrong, for the operator.
    pub error: String,
    /// True when the slot exists already (HTTP 409), else a bad request (HTTP 400).
    pub conflict: bool,
}

/// Checks a run-time attach of `spec` to a vehicle whose slots are `slots`, against the
/// providers loaded now: the slot must be new and well-formed (non-empty, no `/`), a
/// named plugin must be loaded, and its kind must be offered (by that plugin).
///
/// # Errors
/// The field at fault, as [`AttachRefusal`].
pub fn check_attach<'a>(
    spec: &PayloadSpec,
    mut slots: impl Iterator<Item = &'a str>,
    providers: &[ProviderInfo],
) -> Result<(), AttachRefusal> {
    let refuse = |field, error: String| {
        Err(AttachRefusal {
            field,
            error,
            conflict: false,
        })
    };
    if spec.slot.trim().is_empty() || spec.slot.contains('/') {
        return refuse(
            "slot",
            format!("slot `{}` must be non-empty and contain no `/`", spec.slot),
        );
    }
    if slots.any(|s| s == spec.slot) {
        return Err(AttachRefusal {
            field: "slot",
            error: format!(
                "slot `{}` exists already on this vehicle (detach it first)",
                spec.slot
            ),
            conflict: true,
        });
    }
    let names = || {
        let mut all: Vec<String> = providers
            .iter()
            .map(|p| format!("{} ({})", p.name, p.kinds.join(", ")))
            .collect();
        all.sort();
        if all.is_empty() {
            "none".into()
        } else {
            all.join(", ")
        }
    };
    if let Some(name) = &spec.plugin {
        match providers.iter().find(|p| p.name == *name) {
            None => {
                return refuse(
                    "plugin",
                    format!("no plugin named `{name}` is loaded (loaded: {})", names()),
                );
            }
            Some(p) if !p.kinds.contains(&spec.kind) => {
                return refuse(
                    "kind",
                    format!(
                        "plugin `{name}` does not provide payload kind `{}` (it provides: {})",
                        spec.kind,
                        p.kinds.join(", ")
                    ),
                );
            }
            Some(_) => {}
        }
    }
    if provider_for(spec, providers).is_none() {
        return refuse(
            "kind",
            format!(
                "no loaded plugin provides payload kind `{}` (loaded: {})",
                spec.kind,
                names()
            ),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(slot: &str, kind: &str, plugin: Option<&str>) -> PayloadSpec {
        PayloadSpec {
            slot: slot.into(),
            kind: kind.into(),
            plugin: plugin.map(str::to_string),
            isolation: Default::default(),
            config: serde_json::Value::Null,
        }
    }

    fn provider(name: &str, kinds: &[&str]) -> ProviderInfo {
        ProviderInfo {
            name: name.into(),
            version: "1.0.0".into(),
            kinds: kinds.iter().map(|k| k.to_string()).collect(),
        }
    }

    #[test]
    fn a_slot_waits_until_a_provider_of_its_kind_is_loaded() {
        let lamp = spec("lamp", "lamp", None);
        let none: Vec<ProviderInfo> = vec![];
        match placement(&lamp, &none) {
            Placement::Wait(why) => assert!(why.contains("kind `lamp`"), "{why}"),
            other => panic!("{other:?}"),
        }
        let loaded = vec![
            provider("builtin", &["fault-fixture"]),
            provider("lamps", &["lamp"]),
        ];
        assert_eq!(placement(&lamp, &loaded), Placement::Create("lamps".into()));
        // A slot naming its plugin waits for that one, whoever else offers the kind.
        let named = spec("lamp", "lamp", Some("other"));
        match placement(&named, &loaded) {
            Placement::Wait(why) => assert!(why.contains("plugin `other`"), "{why}"),
            other => panic!("{other:?}"),
        }
        // The first provider in factory order wins.
        let two = vec![provider("a", &["lamp"]), provider("b", &["lamp"])];
        assert_eq!(placement(&lamp, &two), Placement::Create("a".into()));
    }

    #[test]
    fn attach_refusals_name_the_field() {
        let loaded = vec![provider("lamps", &["lamp"])];
        let slots = ["gimbal"];
        let ok = spec("lamp", "lamp", None);
        assert_eq!(check_attach(&ok, slots.iter().copied(), &loaded), Ok(()));
        let named = spec("lamp", "lamp", Some("lamps"));
        assert_eq!(check_attach(&named, slots.iter().copied(), &loaded), Ok(()));

        let e = check_attach(
            &spec("gimbal", "lamp", None),
            slots.iter().copied(),
            &loaded,
        )
        .unwrap_err();
        assert_eq!((e.field, e.conflict), ("slot", true), "{e:?}");
        for bad in ["", " ", "a/b"] {
            let e =
                check_attach(&spec(bad, "lamp", None), slots.iter().copied(), &loaded).unwrap_err();
            assert_eq!((e.field, e.conflict), ("slot", false), "{e:?}");
        }
        let e =
            check_attach(&spec("x", "laser", None), slots.iter().copied(), &loaded).unwrap_err();
        assert_eq!(e.field, "kind");
        assert!(
            e.error.contains("`laser`") && e.error.contains("lamps (lamp)"),
            "{e:?}"
        );
        let e = check_attach(
            &spec("x", "lamp", Some("nope")),
            slots.iter().copied(),
            &loaded,
        )
        .unwrap_err();
        assert_eq!(e.field, "plugin");
        assert!(e.error.contains("`nope`"), "{e:?}");
        let e = check_attach(
            &spec("x", "laser", Some("lamps")),
            slots.iter().copied(),
            &loaded,
        )
        .unwrap_err();
        assert_eq!(e.field, "kind");
        assert!(e.error.contains("it provides: lamp"), "{e:?}");
    }
}
