//! At start, each step's group as vehicle ids, from the swarm as it is: a group of listed
//! vehicles must find every one of them, a model's group at least one vehicle of that
//! model; a step without a group is every vehicle. A plan that names what the swarm
//! lacks is refused with the names.

use crate::plan::MissionPlan;
use crate::validate::PlanError;

/// A vehicle of the swarm, as a plan's groups see it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Member {
    /// Vehicle id.
    pub id: String,
    /// Its model's name.
    pub model: String,
}

/// Each step's vehicles, sorted by id (the low-battery reaction's reserves left out: they
/// wait on the ground for their turn).
///
/// # Errors
/// `steps[i].group` for a group that finds no vehicle or lists one the swarm lacks
/// (named); `steps` when the swarm has no vehicle at all.
pub fn groups(plan: &MissionPlan, swarm: &[Member]) -> Result<Vec<Vec<String>>, PlanError> {
    if swarm.is_empty() {
        return Err(PlanError::new("steps", "the swarm has no vehicle"));
    }
    let reserves: &[String] = plan
        .reactions
        .low_battery
        .as_ref()
        .map_or(&[], |l| &l.reserves);
    if let Some(r) = reserves.iter().find(|r| !swarm.iter().any(|m| &m.id == *r)) {
        return Err(PlanError::new(
            "reactions.low_battery.reserves",
            format!("the swarm has no {r}"),
        ));
    }
    let mut all: Vec<String> = swarm
        .iter()
        .map(|m| m.id.clone())
        .filter(|id| !reserves.contains(id))
        .collect();
    all.sort();
    plan.steps
        .iter()
        .enumerate()
        .map(|(i, step)| {
            let Some(name) = &step.group else {
                return Ok(all.clone());
            };
            let field = format!("steps[{i}].group");
            let spec = plan
                .groups
                .get(name)
                .ok_or_else(|| PlanError::new(&field, format!("no group `{name}`")))?;
            let missing: Vec<&str> = spec
                .vehicles
                .iter()
                .filter(|id| !all.contains(id))
                .map(String::as_str)
                .collect();
            if !missing.is_empty() {
                return Err(PlanError::new(
                    field,
                    format!(
                        "group `{name}` lists vehicles the swarm lacks: {}",
                        missing.join(", ")
                    ),
                ));
            }
            let mut ids: Vec<String> = swarm
                .iter()
                .filter(|m| spec.vehicles.contains(&m.id) || spec.model.as_ref() == Some(&m.model))
                .map(|m| m.id.clone())
                .collect();
            ids.sort();
            if ids.is_empty() {
                return Err(PlanError::new(
                    field,
                    format!(
                        "group `{name}` finds no vehicle: the swarm has no `{}`",
                        spec.model.as_deref().unwrap_or("?")
                    ),
                ));
            }
            Ok(ids)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn swarm() -> Vec<Member> {
        [
            ("uav-2", "observation"),
            ("uav-1", "generic"),
            ("uav-3", "generic"),
        ]
        .map(|(id, model)| Member {
            id: id.into(),
            model: model.into(),
        })
        .to_vec()
    }

    fn plan(groups: &str, steps: &str) -> MissionPlan {
        serde_json::from_str(&format!(
            r#"{{"name": "t", "groups": {groups}, "steps": {steps}}}"#
        ))
        .unwrap()
    }

    #[test]
    fn groups_become_vehicle_ids() {
        let p = plan(
            r#"{"obs": {"model": "observation"}, "pair": {"vehicles": ["uav-3", "uav-1"]}}"#,
            r#"[{"kind": "land"}, {"kind": "land", "group": "obs"}, {"kind": "land", "group": "pair"}]"#,
        );
        let g = groups(&p, &swarm()).unwrap();
        assert_eq!(g[0], ["uav-1", "uav-2", "uav-3"]);
        assert_eq!(g[1], ["uav-2"]);
        assert_eq!(g[2], ["uav-1", "uav-3"]);
    }

    #[test]
    fn what_the_swarm_lacks_is_named() {
        let p = plan(
            r#"{"x": {"vehicles": ["uav-1", "uav-9"]}}"#,
            r#"[{"kind": "land", "group": "x"}]"#,
        );
        let e = groups(&p, &swarm()).unwrap_err();
        assert_eq!(e.field, "steps[0].group");
        assert!(
            e.error.contains("uav-9") && !e.error.contains("uav-1,"),
            "{e}"
        );
        let p = plan(
            r#"{"y": {"model": "tanker"}}"#,
            r#"[{"kind": "land", "group": "y"}]"#,
        );
        assert!(
            groups(&p, &swarm())
                .unwrap_err()
                .error
                .contains("no `tanker`")
        );
        assert_eq!(groups(&p, &[]).unwrap_err().field, "steps");
    }
}
