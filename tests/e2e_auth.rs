//! Authentication of the running binary: the refusal to listen on a non-loopback address
//! without tokens, `skein token create`, and tokens from the config on HTTP and the
//! WebSocket stream.

mod support;

use futures_util::StreamExt;
use std::time::Duration;
use support::Process;

#[test]
fn a_non_loopback_address_without_tokens_is_refused_unless_insecure() {
    let mut p = Process::start(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--http",
        "0.0.0.0:0",
    ]);
    let code = p.wait_exit(Duration::from_secs(30));
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}");
    let err = p.stderr_text();
    assert!(
        err.contains("--insecure-no-auth") && err.contains("refusing to listen on 0.0.0.0:0"),
        "{err}"
    );

    let mut p = Process::start(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--http",
        "0.0.0.0:0",
        "--insecure-no-auth",
    ]);
    p.wait_line("dashboard at", Duration::from_secs(60));
    assert!(
        p.stderr_text().contains("WARNING: --insecure-no-auth"),
        "{}",
        p.stderr_text()
    );
}

/// `skein token create --role ROLE --name NAME` → (token, config lines).
fn create(role: &str, name: &str) -> (String, String) {
    let out = std::process::Command::new(support::skein_bin())
        .args(["token", "create", "--role", role, "--name", name])
        .output()
        .expect("skein token create");
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let token = text
        .lines()
        .find_map(|l| l.strip_prefix("token: "))
        .expect("token line")
        .to_string();
    let config = text
        .lines()
        .skip_while(|l| !l.starts_with("[[http.tokens]]"))
        .collect::<Vec<_>>()
        .join("\n");
    (token, config)
}

#[test]
fn tokens_from_the_config_guard_http_and_the_stream() {
    let (viewer, v_cfg) = create("viewer", "watch");
    let (operator, o_cfg) = create("operator", "ops");
    assert_ne!(viewer, operator);
    assert_eq!(viewer.len(), 64);
    let dir = std::env::temp_dir().join(format!("skein-auth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("skein.toml");
    std::fs::write(
        &path,
        format!("[http]\nlisten = \"0.0.0.0:0\"\n\n{v_cfg}\n\n{o_cfg}\n"),
    )
    .unwrap();
    let mut p = Process::start(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--config",
        path.to_str().unwrap(),
    ]);
    let line = p.wait_line("dashboard at", Duration::from_secs(60));
    let port = line
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .unwrap()
        .to_string();
    let base = format!("http://127.0.0.1:{port}");
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(10)))
        .build()
        .into();
    let get = |path: &str, token: Option<&str>| {
        let mut r = agent.get(format!("{base}{path}"));
        if let Some(t) = token {
            r = r.header("Authorization", format!("Bearer {t}"));
        }
        let mut resp = r.call().unwrap();
        let body = resp.body_mut().read_to_string().unwrap_or_default();
        (resp.status().as_u16(), body)
    };
    assert_eq!(get("/api/v1/health", None).0, 200);
    let (s, body) = get("/api/v1/vehicles", None);
    assert_eq!(s, 401, "{body}");
    assert!(body.contains("\"field\":\"authorization\""), "{body}");
    assert_eq!(get("/api/v1/vehicles", Some("nope")).0, 401);
    assert_eq!(get("/api/v1/vehicles", Some(&viewer)).0, 200);
    let (s, body) = get("/api/v1/auth/whoami", Some(&operator));
    assert_eq!(s, 200);
    assert!(
        body.contains("\"name\":\"ops\"") && body.contains("\"role\":\"operator\""),
        "{body}"
    );
    let (s, body) = get("/", None);
    assert_eq!(s, 200, "the dashboard's files need no token");
    assert!(body.contains("<html") || body.contains("<!doctype") || body.contains("<!DOCTYPE"));

    // A viewer may not fly.
    let mut resp = agent
        .post(format!("{base}/api/v1/swarm/commands"))
        .header("Authorization", format!("Bearer {viewer}"))
        .send_json(serde_json::json!({"command": "hold"}))
        .unwrap();
    let body = resp.body_mut().read_to_string().unwrap_or_default();
    assert_eq!(resp.status().as_u16(), 403, "{body}");
    assert!(body.contains("\"required_role\":\"operator\""), "{body}");

    // The stream: refused without a token, a vehicles frame with `?token=`.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let ws = format!("ws://127.0.0.1:{port}/api/v1/stream");
        assert!(tokio_tungstenite::connect_async(&ws).await.is_err());
        let (mut socket, _) = tokio_tungstenite::connect_async(format!("{ws}?token={viewer}"))
            .await
            .expect("stream with the token");
        let first = tokio::time::timeout(Duration::from_secs(10), socket.next())
            .await
            .expect("a frame")
            .expect("open")
            .expect("frame");
        assert!(first.to_text().unwrap().contains("\"vehicles\""));
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// The shipped companion config listens on 0.0.0.0 without tokens: skein will not start on
/// it until tokens are added (safe as shipped).
#[test]
fn the_shipped_companion_config_does_not_start_without_tokens() {
    let config = support::workspace().join("deploy/config/companion.toml");
    let mut p = Process::start(&["up", "--config", config.to_str().unwrap()]);
    let code = p.wait_exit(Duration::from_secs(30));
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}");
    let err = p.stderr_text();
    assert!(
        err.contains("skein token create") && err.contains("--insecure-no-auth"),
        "{err}"
    );
}

/// The dashboard's login in headless Chromium (tests/peers/login_selenium.py).
#[test]
fn the_dashboard_logs_in_and_hides_what_the_role_cannot_do_in_chromium() {
    let (viewer, v_cfg) = create("viewer", "watch");
    let (operator, o_cfg) = create("operator", "ops");
    let dir = std::env::temp_dir().join(format!("skein-auth-ui-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("skein.toml");
    std::fs::write(&path, format!("{v_cfg}\n\n{o_cfg}\n")).unwrap();
    let skein = support::Skein::up(&[
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--config",
        path.to_str().unwrap(),
    ]);
    let url = format!("{}/", skein.base);
    let (code, out, err) = support::run_peer(
        "login_selenium.py",
        &[
            "--url",
            &url,
            "--viewer-token",
            &viewer,
            "--operator-token",
            &operator,
        ],
        Duration::from_secs(180),
    );
    assert_eq!(
        code,
        Some(0),
        "login_selenium.py\n--- stdout\n{out}\n--- stderr\n{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `[http] tls_cert`, `tls_key`: the API answers over TLS (a client trusting the
/// self-signed certificate) and not in plain HTTP.
#[test]
fn the_api_serves_https_with_a_configured_certificate() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let dir = std::env::temp_dir().join(format!("skein-tls-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ok = std::process::Command::new("openssl")
        .args([
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-days",
            "1",
            "-subj",
            "/CN=localhost",
            "-addext",
            "subjectAltName=DNS:localhost,IP:127.0.0.1",
            "-addext",
            "basicConstraints=critical,CA:FALSE",
            "-keyout",
            "key.pem",
            "-out",
            "cert.pem",
        ])
        .current_dir(&dir)
        .output()
        .expect("openssl");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let config = dir.join("skein.toml");
    std::fs::write(
        &config,
        "[http]\ntls_cert = \"cert.pem\"\ntls_key = \"key.pem\"\n",
    )
    .unwrap();
    let mut p = Process::start(&[
        "up",
        "--sim",
        "1",
        "--sim-base-port",
        "0",
        "--http",
        "127.0.0.1:0",
        "--config",
        config.to_str().unwrap(),
    ]);
    let line = p.wait_line("dashboard at", Duration::from_secs(60));
    assert!(line.contains("https://127.0.0.1:"), "{line}");
    let port: u16 = line
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .unwrap()
        .parse()
        .unwrap();

    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        use rustls::pki_types::pem::PemObject;
        let mut roots = rustls::RootCertStore::empty();
        roots
            .add(rustls::pki_types::CertificateDer::from_pem_file(dir.join("cert.pem")).unwrap())
            .unwrap();
        let cfg = rustls::ClientConfig::builder_with_provider(std::sync::Arc::new(
            rustls::crypto::ring::default_provider(),
        ))
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
        let connector = tokio_rustls::TlsConnector::from(std::sync::Arc::new(cfg));
        let tcp = tokio::net::TcpStream::connect(("127.0.0.1", port))
            .await
            .unwrap();
        let name = rustls::pki_types::ServerName::try_from("localhost").unwrap();
        let mut tls = connector.connect(name, tcp).await.expect("TLS handshake");
        tls.write_all(
            b"GET /api/v1/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n",
        )
        .await
        .unwrap();
        let mut answer = Vec::new();
        let _ = tokio::time::timeout(Duration::from_secs(10), tls.read_to_end(&mut answer)).await;
        let answer = String::from_utf8_lossy(&answer);
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");

        // Plain HTTP on the same port gets no HTTP answer.
        let mut plain = tokio::net::TcpStream::connect(("127.0.0.1", port))
            .await
            .unwrap();
        plain
            .write_all(b"GET /api/v1/health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .await
            .unwrap();
        let mut answer = Vec::new();
        let _ = tokio::time::timeout(Duration::from_secs(10), plain.read_to_end(&mut answer)).await;
        assert!(!answer.starts_with(b"HTTP/1.1 200"));
    });
    let _ = std::fs::remove_dir_all(&dir);
}
