//! Sets `cfg(freenect_missing)` when the `freenect` feature is on but libfreenect-sys was
//! built without the system library (its build script reports `DEP_FREENECT_AVAILABLE=0`).

fn main() {
    println!("cargo::rustc-check-cfg=cfg(freenect_missing)");
    println!("cargo::rerun-if-changed=build.rs");
    println!("cargo::rerun-if-env-changed=DEP_FREENECT_AVAILABLE");
    if std::env::var("DEP_FREENECT_AVAILABLE").is_ok_and(|v| v == "0") {
        println!("cargo::rustc-cfg=freenect_missing");
    }
}
