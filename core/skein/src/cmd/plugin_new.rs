//! `skein plugin new NAME [--kind KIND] [--dir DIR] [--sdk PATH]`: writes a payload
//! plugin crate that builds as it is, so a newcomer starts from working code.
//!
//! The crate is the example plugin's shape cut to the essentials: a `Cargo.toml` (a
//! `cdylib`, its own workspace, `skein-plugin-sdk` by path: this skein's SDK by absolute
//! path unless `--sdk` gives another), `src/lib.rs` with one payload kind, its config,
//! three commands and `export_plugin!`, unit tests of its logic, and a `README.md` saying
//! how to build, drop in, load and attach it. When skein's own `Cargo.lock` is found next
//! to the SDK it is copied too, so the plugin builds against the very dependency versions
//! skein was built with (and offline).

use std::path::{Path, PathBuf};

/// Arguments of `skein plugin new`.
#[derive(clap::Args, Debug)]
pub struct NewArgs {
    /// Plugin (and crate) name: lower-case letters, digits, `-` and `_`, starting with a
    /// letter. The library is `lib<name with _ for ->.so`.
    pub name: String,
    /// The payload kind it provides (what vehicle models and attach requests ask for);
    /// default: the name.
    #[arg(long)]
    pub kind: Option<String>,
    /// Directory to create (must not exist or be empty); default: `./NAME`.
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Path of the `skein-plugin-sdk` crate the plugin builds against; default: the SDK of
    /// the skein source tree this binary was built from.
    #[arg(long)]
    pub sdk: Option<PathBuf>,
}

/// The SDK of the source tree this binary was built from.
fn default_sdk() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../plugins/sdk")
}

/// Checks a plugin name (also used as crate name and payload kind).
///
/// # Errors
/// Names what is wrong.
pub fn check_name(what: &str, name: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let first_ok = chars.next().is_some_and(|c| c.is_ascii_lowercase());
    let rest_ok = name
        .chars()
        .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_');
    if first_ok && rest_ok && name.len() <= 64 {
        Ok(())
    } else {
        Err(format!(
            "{what} `{name}`: use lower-case letters, digits, `-` and `_`, starting with a letter"
        ))
    }
}

/// `lamp-post` → `LampPost`.
fn type_name(name: &str) -> String {
    name.split(['-', '_'])
        .filter(|p| !p.is_empty())
        .map(|p| {
            let mut c = p.chars();
            c.next()
                .map(|f| f.to_ascii_uppercase().to_string() + c.as_str())
                .unwrap_or_default()
        })
        .collect()
}

/// The files of a new plugin crate (relative path, content).
pub fn render(name: &str, kind: &str, sdk: &Path) -> Vec<(PathBuf, String)> {
    let ty = type_name(name);
    let lib_file = format!("lib{}.so", name.replace('-', "_"));
    let cargo = format!(
        r#"[package]
name = "{name}"
version = "0.1.0"
edition = "2024"
publish = false

[lib]
# A C-ABI shared library skein loads at run time.
crate-type = ["cdylib"]

[dependencies]
# The only crate a plugin links: the SDK of the skein it runs in.
skein-plugin-sdk = {{ path = "{sdk}" }}

# A workspace of its own, wherever the crate lives.
[workspace]
"#,
        sdk = sdk.display()
    );
    let lib = TEMPLATE
        .replace("__NAME__", name)
        .replace("__KIND__", kind)
        .replace("__TYPE__", &ty);
    let readme = format!(
        r#"# {name}: a skein payload plugin (kind `{kind}`)

Made by `skein plugin new`. Build it, drop it into skein's plugin directory, load it:

```sh
cargo build --release
cp target/release/{lib_file} /path/to/plugin-dir/
curl -X POST localhost:8080/api/v1/plugins/load -d '{{"file": "{lib_file}"}}'
# vehicles whose model asks for kind `{kind}` start their slots at once; or attach one:
curl -X POST localhost:8080/api/v1/vehicles/uav-1/payloads -d '{{"slot": "{kind}", "kind": "{kind}"}}'
curl -X POST localhost:8080/api/v1/vehicles/uav-1/payloads/{kind} -d '{{"command": "ping"}}'
```

`cargo test` runs the unit tests of its logic. See skein's `plugins/README.md`.
"#
    );
    vec![
        (PathBuf::from("Cargo.toml"), cargo),
        (PathBuf::from("src/lib.rs"), lib),
        (PathBuf::from("README.md"), readme),
        (PathBuf::from(".gitignore"), "/target\n".to_string()),
    ]
}

/// `skein plugin new`: writes the crate; returns its directory.
///
/// # Errors
/// A bad name or kind, a directory that exists and is not empty, an SDK path that is not
/// the SDK, or a file that cannot be written.
pub fn run(args: NewArgs) -> Result<PathBuf, String> {
    check_name("plugin name", &args.name)?;
    let kind = args.kind.clone().unwrap_or_else(|| args.name.clone());
    check_name("--kind", &kind)?;
    let dir = args
        .dir
        .clone()
        .unwrap_or_else(|| PathBuf::from(&args.name));
    if dir.exists()
        && std::fs::read_dir(&dir)
            .map_err(|e| format!("--dir {}: {e}", dir.display()))?
            .next()
            .is_some()
    {
        return Err(format!(
            "--dir {}: exists and is not empty (choose another)",
            dir.display()
        ));
    }
    let sdk = args.sdk.clone().unwrap_or_else(default_sdk);
    let sdk = sdk.canonicalize().map_err(|e| {
        format!(
            "the plugin SDK at {} is not there ({e}): give --sdk PATH (skein's plugins/sdk)",
            sdk.display()
        )
    })?;
    let manifest = std::fs::read_to_string(sdk.join("Cargo.toml")).unwrap_or_default();
    if !manifest.contains("name = \"skein-plugin-sdk\"") {
        return Err(format!(
            "--sdk {}: not the skein-plugin-sdk crate (no such package in its Cargo.toml)",
            sdk.display()
        ));
    }
    let mut files = render(&args.name, &kind, &sdk);
    // skein's lock file: the same dependency versions as skein, no registry lookup.
    if let Some(lock) = sdk
        .parent()
        .and_then(Path::parent)
        .map(|root| root.join("Cargo.lock"))
        .and_then(|l| std::fs::read_to_string(l).ok())
    {
        files.push((PathBuf::from("Cargo.lock"), lock));
    }
    for (rel, text) in &files {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
        }
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(dir)
}

/// `src/lib.rs` of a new plugin (`__NAME__`, `__KIND__`, `__TYPE__` replaced).
const TEMPLATE: &str = r#"//! `__NAME__`: a skein payload plugin providing the payload kind `__KIND__`.
//!
//! Made by `skein plugin new`; replace the bodies with your device. The config and the
//! commands are serde types read by the SDK's `args` (errors name the field); the logic
//! sits in plain methods (`from_config`, `command`) so `cargo test` checks it without
//! skein; the `Plugin` impl wires it to skein's host services.
//!
//! Config (all optional): `{"rate_hz": 1.0, "value": 0.0}`.
//! Commands (`POST /api/v1/vehicles/{id}/payloads/{slot}`):
//! - `{"command": "ping"}` → `{"pong": true, "plugin": "__NAME__", "version", "vehicle"}`
//! - `{"command": "set", "value": 2.5}` → the state
//! - `{"command": "status"}` → the state
//!
//! Published state: `{"value": 2.5, "ticks": 12}`. At shutdown it raises a `__NAME__`
//! event `{"shutdown": true, "value"}` on skein's stream.

use skein_plugin_sdk::args;
use skein_plugin_sdk::serde::Deserialize;
use skein_plugin_sdk::serde_json::{Value, json};
use skein_plugin_sdk::{Context, Plugin, export_plugin};

/// The slot's config. serde reads it (the SDK re-exports serde, hence `crate = ...`);
/// `deny_unknown_fields` refuses a typo, naming it.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde", deny_unknown_fields)]
struct Config {
    /// Tick rate, Hz, 0 to 100; default 1.
    rate_hz: Option<f64>,
    /// The initial value; default 0.
    value: Option<f64>,
}

/// The commands: one variant per `command` name (snake_case), its fields inside.
#[derive(Deserialize)]
#[serde(crate = "skein_plugin_sdk::serde")]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
enum Command {
    /// `{"command": "ping"}`.
    Ping,
    /// `{"command": "set", "value": 2.5}`.
    Set { value: f64 },
    /// `{"command": "status"}`.
    Status,
}

/// One instance of the `__KIND__` payload (one slot on one vehicle).
pub struct __TYPE__ {
    /// Tick rate, Hz (0: never ticked).
    rate_hz: f64,
    /// The value `set` changes.
    value: f64,
    /// Ticks since creation.
    ticks: u64,
}

impl __TYPE__ {
    /// Reads the slot's config (`Value::Null` when the slot has none).
    fn from_config(config: Value) -> Result<Self, String> {
        // Every error starts with the field at fault (`rate_hz: 500 is outside [0, 100]`),
        // which skein's API answers as `"field": "rate_hz"`.
        let cfg: Config = args::config(config)?;
        Ok(__TYPE__ {
            rate_hz: args::in_range("rate_hz", cfg.rate_hz.unwrap_or(1.0), 0.0, 100.0)?,
            value: cfg.value.unwrap_or(0.0),
            ticks: 0,
        })
    }

    /// What this instance publishes (also the answer to `set` and `status`).
    fn state(&self) -> Value {
        json!({"value": self.value, "ticks": self.ticks})
    }

    /// An operator command, without host services.
    fn command(&mut self, command: Value) -> Result<Value, String> {
        // Unknown commands and fields, missing and mistyped ones: refused, naming them.
        match args::command(command)? {
            Command::Ping => {
                Ok(json!({"pong": true, "plugin": Self::NAME, "version": Self::VERSION}))
            }
            Command::Set { value } => {
                self.value = value;
                Ok(self.state())
            }
            Command::Status => Ok(self.state()),
        }
    }
}

impl Plugin for __TYPE__ {
    // The name must be unique among the plugins skein has loaded; the kinds are what
    // vehicle models and attach requests ask for.
    const NAME: &'static str = "__NAME__";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const KINDS: &'static [&'static str] = &["__KIND__"];

    fn create(_kind: &str, config: Value, ctx: &Context) -> Result<Self, String> {
        let me = Self::from_config(config)?;
        ctx.log_info(&format!("__NAME__ payload created on {}", ctx.vehicle_id()));
        Ok(me)
    }

    fn tick_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    fn tick(&mut self, ctx: &Context, _dt_s: f64) -> Result<(), String> {
        self.ticks += 1;
        ctx.publish_state(&self.state())
    }

    fn handle(&mut self, ctx: &Context, command: Value) -> Result<Value, String> {
        let mut answer = self.command(command)?;
        if answer.get("pong").is_some() {
            answer["vehicle"] = json!(ctx.vehicle_id());
        } else {
            ctx.publish_state(&self.state())?;
        }
        Ok(answer)
    }

    fn shutdown(&mut self, ctx: &Context) {
        // Runs before the instance is dropped (detach, unload, reload, skein stopping):
        // put your device back the way you found it. Here, just say so on the stream.
        let _ = ctx.emit_event("__NAME__", &json!({"shutdown": true, "value": self.value}));
    }
}

// The C entry point skein looks for (`skein_plugin_entry`).
export_plugin!(__TYPE__);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_has_defaults_and_refuses_unknown_fields() {
        let p = __TYPE__::from_config(Value::Null).unwrap();
        assert_eq!((p.rate_hz, p.value), (1.0, 0.0));
        let e = __TYPE__::from_config(json!({"rate": 2.0})).err().unwrap();
        assert!(e.starts_with("rate: unknown field `rate`"), "{e}");
        let e = __TYPE__::from_config(json!({"rate_hz": 500})).err().unwrap();
        assert_eq!(e, "rate_hz: 500 is outside [0, 100]");
    }

    #[test]
    fn commands_change_and_report_the_state() {
        let mut p = __TYPE__::from_config(json!({"rate_hz": 0.0})).unwrap();
        assert_eq!(p.command(json!({"command": "ping"})).unwrap()["pong"], true);
        let s = p.command(json!({"command": "set", "value": 2.5})).unwrap();
        assert_eq!(s["value"], 2.5);
        assert_eq!(
            p.command(json!({"command": "status"})).unwrap()["value"],
            2.5
        );
        let e = p.command(json!({"command": "set"})).unwrap_err();
        assert_eq!(e, "value: missing field `value`");
        let e = p.command(json!({"command": "explode"})).unwrap_err();
        assert!(e.starts_with("command: unknown command `explode`"), "{e}");
    }
}
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked() {
        assert!(check_name("name", "lamp").is_ok());
        assert!(check_name("name", "lamp-post_2").is_ok());
        for bad in ["", "Lamp", "2lamp", "la mp", "lamp/x", "-lamp"] {
            assert!(check_name("name", bad).is_err(), "{bad}");
        }
        assert_eq!(type_name("lamp-post_2"), "LampPost2");
    }

    #[test]
    fn the_crate_points_at_the_sdk_and_exports_the_kind() {
        let files = render("lamp-post", "lamp", Path::new("/opt/skein/plugins/sdk"));
        let get = |p: &str| {
            files
                .iter()
                .find(|(f, _)| f == Path::new(p))
                .map(|(_, t)| t.clone())
                .unwrap()
        };
        let cargo = get("Cargo.toml");
        assert!(cargo.contains("name = \"lamp-post\""), "{cargo}");
        assert!(cargo.contains("crate-type = [\"cdylib\"]"), "{cargo}");
        assert!(
            cargo.contains("path = \"/opt/skein/plugins/sdk\""),
            "{cargo}"
        );
        assert!(cargo.contains("\n[workspace]\n"), "{cargo}");
        let lib = get("src/lib.rs");
        assert!(lib.contains("export_plugin!(LampPost);"));
        assert!(lib.contains("const KINDS: &'static [&'static str] = &[\"lamp\"];"));
        assert!(lib.contains("const NAME: &'static str = \"lamp-post\";"));
        assert!(!lib.contains("__"), "every placeholder replaced");
        assert!(get("README.md").contains("liblamp_post.so"));
    }
}
