//! Finds the system libfreenect with pkg-config and links libfreenect_sync next to it.
//!
//! When the library is missing the crate still builds (so `cargo test --workspace` works on a
//! fresh machine): the build prints a warning and sets `cfg(freenect_missing)`, under which no
//! extern block is compiled and `AVAILABLE` is `false`. With `LIBFREENECT_REQUIRED=1` (CI) a
//! missing library is a hard error instead. Dependents' build scripts see the outcome as
//! `DEP_FREENECT_AVAILABLE` (`1` or `0`).

use std::env;
use std::process::ExitCode;

fn main() -> ExitCode {
    println!("cargo::rustc-check-cfg=cfg(freenect_missing)");
    println!("cargo:rerun-if-env-changed=LIBFREENECT_REQUIRED");
    println!("cargo:rerun-if-changed=build.rs");

    let required = env::var("LIBFREENECT_REQUIRED").is_ok_and(|v| v == "1");
    match pkg_config::Config::new()
        .atleast_version("0.5")
        .probe("libfreenect")
    {
        Ok(lib) => {
            // pkg-config's `--libs libfreenect` names only -lfreenect; the synchronous wrapper
            // is a separate library in the same directory.
            for dir in &lib.link_paths {
                println!("cargo:rustc-link-search=native={}", dir.display());
            }
            println!("cargo:rustc-link-lib=freenect_sync");
            // Seen by dependents' build scripts as DEP_FREENECT_AVAILABLE.
            println!("cargo::metadata=available=1");
            ExitCode::SUCCESS
        }
        Err(e) if required => {
            eprintln!(
                "error: libfreenect was not found by pkg-config and LIBFREENECT_REQUIRED=1 is set.\n\
                 How to fix: `sudo apt-get install libfreenect-dev` (Debian/Ubuntu), or point \
                 PKG_CONFIG_PATH at libfreenect.pc.\npkg-config said: {e}"
            );
            ExitCode::FAILURE
        }
        Err(e) => {
            // The full pkg-config report goes to the build script's stderr (`cargo build -vv`).
            eprintln!("{e}");
            println!(
                "cargo:warning=libfreenect not found by pkg-config; building \
                 libfreenect-sys without it (AVAILABLE = false). Install it with \
                 `apt-get install libfreenect-dev`; set LIBFREENECT_REQUIRED=1 to make this an error."
            );
            println!("cargo:rustc-cfg=freenect_missing");
            println!("cargo::metadata=available=0");
            ExitCode::SUCCESS
        }
    }
}
