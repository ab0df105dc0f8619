//! What the tests that run the example binaries share.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;

/// The example binary `name`, built now if it is missing or stale: `cargo build --example
/// NAME` with the profile and features this test was built with, so that `cargo test --test
/// NAME` runs what it tests instead of skipping.
///
/// # Panics
/// When the example does not build: the test fails, it never passes silently.
#[must_use]
pub fn example_bin(name: &str) -> PathBuf {
    static BUILT: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let exe = std::env::current_exe().unwrap();
    // target/<profile dir>/deps/<test>-<hash> → target/<profile dir>/examples/<name>
    let dir = exe.parent().and_then(Path::parent).unwrap();
    let bin = dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    let mut built = BUILT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if !built.iter().any(|b| b == name) {
        // `cargo test` builds its targets with the `test` profile (`bench` with `--release`).
        let profile = match dir.file_name().and_then(|n| n.to_str()) {
            Some("debug") => "test",
            Some("release") => "bench",
            Some(other) => other,
            None => "test",
        };
        let mut features = Vec::new();
        for (on, feature) in [
            (cfg!(feature = "parallel"), "parallel"),
            (cfg!(feature = "freenect"), "freenect"),
            (cfg!(feature = "gpio"), "gpio"),
        ] {
            if on {
                features.push(feature);
            }
        }
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let status = Command::new(cargo)
            .args(["build", "--quiet", "--example", name, "--profile", profile])
            .args(["--no-default-features", "--features", &features.join(",")])
            .arg("--manifest-path")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml"))
            .status()
            .expect("cargo runs");
        assert!(status.success(), "cargo build --example {name} failed");
        built.push(name.to_owned());
    }
    assert!(bin.exists(), "{} was not built", bin.display());
    bin
}

/// A quick simulated scan's flags: 4 snapshots of 1 frame, 3 mm leaves.
#[allow(dead_code)] // not every test crate that includes this module scans
pub const SMALL_SCAN: [&str; 6] = ["--snapshots", "4", "--frames", "1", "--leaf", "0.003"];

/// Runs the example `name` ([`example_bin`]) with `args` in `cwd`, without a turntable
/// token from the environment.
pub fn run_example(name: &str, args: &[&str], cwd: &Path) -> Output {
    Command::new(example_bin(name))
        .args(args)
        .current_dir(cwd)
        .env_remove("VOXOCT_TURNTABLE_TOKEN")
        .output()
        .unwrap()
}

/// Asserts that `out` is a refusal as a user should see it: a non-zero exit, no panic, and
/// stderr naming every one of `needles` (case-insensitively). Returns stderr.
#[allow(dead_code)] // not every test crate that includes this module refuses anything
pub fn assert_refused(out: &Output, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "should fail: {stderr}");
    assert!(!stderr.contains("panicked"), "panicked: {stderr}");
    let lower = stderr.to_lowercase();
    for n in needles {
        assert!(
            lower.contains(&n.to_lowercase()),
            "stderr should mention {n:?}: {stderr}"
        );
    }
    stderr
}

/// Runs the `scan` example quietly with `args` in a new empty directory and asserts a clean
/// refusal: [`assert_refused`] naming `needle`, and nothing left in the directory — no
/// output file, partial or temporary.
#[allow(dead_code)]
pub fn assert_scan_fails_cleanly(args: &[&str], needle: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = run_example("scan", &[args, &["-q"]].concat(), dir.path());
    assert_refused(&out, &[needle]);
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "{args:?} left files behind: {left:?}");
}
