//! What the tests that run the example binaries share.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The example binary `name` that `cargo test` built next to this test, or `None` with a
/// note when only the test target was built: `cargo test --test NAME` builds no examples,
/// `cargo test --workspace` (the README's command, and CI's) does.
pub fn example_bin(name: &str) -> Option<PathBuf> {
    let exe = std::env::current_exe().unwrap();
    // target/<profile>/deps/<test>-<hash> → target/<profile>/examples/<name>
    let dir = exe.parent().and_then(Path::parent).unwrap();
    let bin = dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    if !bin.exists() {
        eprintln!(
            "SKIPPED: {} is not built; run `cargo test --workspace`",
            bin.display()
        );
        return None;
    }
    Some(bin)
}

/// Runs the example `name` with `args` in `cwd` (without a turntable token from the
/// environment), or `None` when it is not built.
pub fn run_example(name: &str, args: &[&str], cwd: &Path) -> Option<Output> {
    Some(
        Command::new(example_bin(name)?)
            .args(args)
            .current_dir(cwd)
            .env_remove("VOXOCT_TURNTABLE_TOKEN")
            .output()
            .unwrap(),
    )
}
