//! The coordinator's missions: every plan posted, by id, with its run, kept in memory and
//! in the missions directory (`<dir>/<id>.json`, the plan and the last status), so that
//! plans outlive a restart and can be listed and flown again. Files are written by a
//! blocking task, through a `.part` file renamed: the coordinator never waits on disk.

use serde::{Deserialize, Serialize};
use skein_mission::{MissionPlan, MissionRun, RunStatus};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A mission as the API shows it (`GET /api/v1/missions/{id}`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct MissionInfo {
    /// Its id (`m-<n>`).
    pub id: String,
    /// The plan's name.
    pub name: String,
    /// Its run's state and progress.
    #[serde(flatten)]
    pub status: RunStatus,
    /// The plan.
    pub plan: MissionPlan,
}

/// What a mission's file holds.
#[derive(Serialize, Deserialize)]
struct Stored {
    id: String,
    plan: MissionPlan,
}

/// One mission: its plan and, once started, its run.
#[derive(Debug, Clone)]
pub(crate) struct Mission {
    pub(crate) plan: MissionPlan,
    pub(crate) run: Option<MissionRun>,
}

/// Every mission of this coordinator (see the module docs).
#[derive(Debug, Default)]
pub(crate) struct Store {
    dir: Option<PathBuf>,
    missions: BTreeMap<String, Mission>,
    next: u64,
    /// Each vehicle's consumption measured in flight (see `consumption`).
    pub(crate) consumption: BTreeMap<String, skein_mission::consumption::ConsumptionFit>,
}

impl Store {
    /// The missions stored in `dir` (none when `None`: kept in memory only). A file that
    /// cannot be read is skipped with a warning.
    pub(crate) fn open(dir: Option<PathBuf>) -> Store {
        let mut store = Store {
            dir,
            ..Store::default()
        };
        let Some(dir) = &store.dir else {
            return store;
        };
        let Ok(entries) = std::fs::read_dir(dir) else {
            return store;
        };
        for path in entries.flatten().map(|e| e.path()) {
            if path.extension().is_none_or(|e| e != "json") {
                continue;
            }
            match std::fs::read(&path)
                .map_err(|e| e.to_string())
                .and_then(|b| serde_json::from_slice::<Stored>(&b).map_err(|e| e.to_string()))
            {
                Ok(s) => {
                    store.next = store.next.max(number(&s.id) + 1);
                    store.missions.insert(
                        s.id,
                        Mission {
                            plan: s.plan,
                            run: None,
                        },
                    );
                }
                Err(e) => tracing::warn!("mission file {}: {e}", path.display()),
            }
        }
        store
    }

    /// Stores a new plan; its id.
    pub(crate) fn add(&mut self, plan: MissionPlan) -> String {
        self.next += 1;
        let id = format!("m-{}", self.next);
        self.write(&id, &plan);
        self.missions
            .insert(id.clone(), Mission { plan, run: None });
        id
    }

    fn write(&self, id: &str, plan: &MissionPlan) {
        let Some(dir) = self.dir.clone() else {
            return;
        };
        let stored = Stored {
            id: id.to_string(),
            plan: plan.clone(),
        };
        let id = id.to_string();
        tokio::task::spawn_blocking(move || {
            let write = || -> std::io::Result<()> {
                std::fs::create_dir_all(&dir)?;
                let path = dir.join(format!("{id}.json"));
                let part = path.with_extension("json.part");
                std::fs::write(&part, serde_json::to_vec_pretty(&stored)?)?;
                std::fs::rename(&part, &path)
            };
            if let Err(e) = write() {
                tracing::warn!("mission {id} not stored in {}: {e}", dir.display());
            }
        });
    }

    /// Takes over mission `id` from another coordinator, flying `run` (stored, its plan
    /// written as if posted here; an earlier mission of that id is replaced).
    pub(crate) fn adopt(&mut self, id: &str, run: MissionRun) {
        let plan = run.plan().clone();
        self.write(id, &plan);
        self.next = self.next.max(number(id));
        self.missions.insert(
            id.to_string(),
            Mission {
                plan,
                run: Some(run),
            },
        );
    }

    /// Lets the flying mission go (its run dropped: it is ready here again); its id.
    pub(crate) fn let_go(&mut self) -> Option<String> {
        let (id, m) = self.flying()?;
        m.run = None;
        Some(id.clone())
    }

    pub(crate) fn get(&self, id: &str) -> Option<&Mission> {
        self.missions.get(id)
    }

    pub(crate) fn get_mut(&mut self, id: &str) -> Option<&mut Mission> {
        self.missions.get_mut(id)
    }

    /// The mission flying now (running, paused or aborting), if any.
    pub(crate) fn flying(&mut self) -> Option<(&String, &mut Mission)> {
        self.missions.iter_mut().find(|(_, m)| {
            m.run.as_ref().is_some_and(|r| {
                matches!(
                    r.status().state,
                    skein_mission::RunState::Running | skein_mission::RunState::Paused
                )
            })
        })
    }

    /// Every mission as the API shows it, by id.
    pub(crate) fn infos(&self) -> Vec<MissionInfo> {
        self.missions.iter().map(|(id, m)| info(id, m)).collect()
    }
}

/// `m` as the API shows it.
pub(crate) fn info(id: &str, m: &Mission) -> MissionInfo {
    let status = match &m.run {
        Some(r) => r.status().clone(),
        None => MissionRun::new(m.plan.clone(), vec![vec![]; m.plan.steps.len()])
            .status()
            .clone(),
    };
    MissionInfo {
        id: id.to_string(),
        name: m.plan.name.clone(),
        status,
        plan: m.plan.clone(),
    }
}

fn number(id: &str) -> u64 {
    id.strip_prefix("m-")
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}
