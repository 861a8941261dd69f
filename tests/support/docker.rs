//! Docker for the deployment tests: the images `deploy/docker/build-image.sh` builds, the
//! compose projects of `deploy/compose/`, containers' logs and exits. Everything a test
//! makes is named after its process (`skein-test-<pid>…`) and removed when its guard
//! drops (the base images make-base.sh makes are kept on purpose: the next run reuses
//! them).

use super::workspace;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// `docker <args>`, its output whatever the status.
pub fn try_docker(args: &[&str]) -> Output {
    Command::new("docker")
        .args(args)
        .output()
        .expect("run docker (tests/run.sh needs Docker)")
}

/// `docker <args>`; asserts success and returns stdout, trimmed.
pub fn docker(args: &[&str]) -> String {
    let out = try_docker(args);
    assert!(
        out.status.success(),
        "docker {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// An image this test built; removed on drop.
pub struct Image {
    /// Its tag (`skein:test-<pid>-amd64`).
    pub tag: String,
    /// Its size, bytes (`docker image inspect`'s `Size`).
    pub size: u64,
    /// How long `build-image.sh` took, seconds (the base image included when it was
    /// made).
    pub build_s: f64,
}

impl Image {
    /// `deploy/docker/build-image.sh --arch ARCH --tag TAG BIN_DIR` with `env`: stages,
    /// strips and builds (making the base image first when missing).
    pub fn build(arch: &str, tag: &str, bin_dir: &std::path::Path, env: &[(&str, &str)]) -> Image {
        let started = Instant::now();
        let out = Command::new(workspace().join("deploy/docker/build-image.sh"))
            .args(["--arch", arch, "--tag", tag])
            .arg(bin_dir)
            .envs(env.iter().copied())
            .output()
            .expect("run build-image.sh");
        let build_s = started.elapsed().as_secs_f64();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "build-image.sh failed:\n{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (built, size) = stdout
            .split_once(' ')
            .expect("build-image.sh prints `TAG SIZE`");
        assert_eq!(built, tag);
        Image {
            tag: tag.to_string(),
            size: size.trim().parse().expect("size"),
            build_s,
        }
    }

    /// The image's architecture (`amd64`, `arm64`).
    pub fn architecture(&self) -> String {
        docker(&["image", "inspect", "-f", "{{.Architecture}}", &self.tag])
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        let _ = try_docker(&["rmi", "-f", &self.tag]);
    }
}

/// The compose command of this machine: Compose v2 (`docker compose`) if the plugin is
/// there, else v1 (`docker-compose`, Debian's package).
pub fn compose_command() -> Vec<String> {
    let v2 = Command::new("docker")
        .args(["compose", "version"])
        .output()
        .is_ok_and(|o| o.status.success());
    if v2 {
        vec!["docker".into(), "compose".into()]
    } else {
        vec!["docker-compose".into()]
    }
}

/// A compose project of one of `deploy/compose/`'s files, with its own name and
/// environment; `down` on drop (containers and network removed at once).
pub struct Compose {
    command: Vec<String>,
    /// The project's name (`skein-test-<pid>`).
    pub project: String,
    file: std::path::PathBuf,
    env: Vec<(String, String)>,
}

impl Compose {
    /// The project `project` of `deploy/compose/<file>` with `env` (the file's `${…}`).
    pub fn new(file: &str, project: &str, env: &[(&str, String)]) -> Compose {
        Compose {
            command: compose_command(),
            project: project.to_string(),
            file: workspace().join("deploy/compose").join(file),
            env: env
                .iter()
                .map(|(k, v)| (k.to_string(), v.clone()))
                .collect(),
        }
    }

    /// `compose -p PROJECT -f FILE <args>`, its output whatever the status.
    pub fn run(&self, args: &[&str]) -> Output {
        Command::new(&self.command[0])
            .args(&self.command[1..])
            .arg("-p")
            .arg(&self.project)
            .arg("-f")
            .arg(&self.file)
            .args(args)
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .output()
            .expect("run compose (tests/run.sh installs docker-compose if missing)")
    }

    /// As [`Compose::run`]; asserts success.
    pub fn ok(&self, args: &[&str]) -> String {
        let out = self.run(args);
        assert!(
            out.status.success(),
            "compose {}: {}{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    }

    /// The container id of `service`.
    pub fn container(&self, service: &str) -> String {
        let id = self.ok(&["ps", "-q", service]);
        assert!(!id.is_empty(), "no container for {service}");
        id
    }

    /// The project's network `name` (`<project>_<name>`).
    pub fn network(&self, name: &str) -> String {
        format!("{}_{name}", self.project)
    }
}

impl Drop for Compose {
    fn drop(&mut self) {
        let _ = self.run(&["down", "-t", "0", "-v", "--remove-orphans"]);
    }
}

/// A running `docker <args>` whose stdout and stderr lines are kept (`docker logs -f`,
/// `docker events`); killed on drop.
pub struct Follower {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
    /// Printed with the last lines when the test fails ([`Follower::dumped_on_failure`]).
    label: Option<String>,
}

impl Follower {
    /// Starts `docker <args>`.
    pub fn start(args: &[&str]) -> Follower {
        let mut child = Command::new("docker")
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run docker");
        let lines = Arc::new(Mutex::new(Vec::new()));
        for pipe in [
            Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().unwrap()),
        ] {
            let l = lines.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                    l.lock().unwrap().push(line);
                }
            });
        }
        Follower {
            child,
            lines,
            label: None,
        }
    }

    /// Prints the last 200 lines under `label` if the test panics while this follower
    /// lives (a container's log is gone once the test's compose project is removed).
    pub fn dumped_on_failure(mut self, label: &str) -> Follower {
        super::failure::keep_panic_messages();
        self.label = Some(label.to_string());
        self
    }

    /// Every line so far.
    pub fn lines(&self) -> Vec<String> {
        self.lines.lock().unwrap().clone()
    }

    /// Every line so far, as one text.
    pub fn text(&self) -> String {
        self.lines().join("\n")
    }
}

impl Drop for Follower {
    fn drop(&mut self) {
        if let Some(label) = &self.label
            && std::thread::panicking()
        {
            let lines = self.lines();
            let tail = &lines[lines.len().saturating_sub(200)..];
            eprintln!("---- last {} lines of {label} ----", tail.len());
            for line in tail {
                eprintln!("{label}: {line}");
            }
            super::failure::repeat_failure();
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
