//! The dashboard in `web-ui/` is embedded with `include_dir!`, which Cargo does not track:
//! rebuild this crate whenever a file there changes.
fn main() {
    println!("cargo:rerun-if-changed=../../web-ui");
}
