//! Inserts the bench snapshot a few times (serial): a small binary for profilers such
//! as `valgrind --tool=callgrind` (instructions per triangle are reliable under load).
//!
//! `cargo run --release -p voxoct-core --example profile_insert -- [reps]`

use voxoct_core::Octree;

#[path = "../tests/support/snapshot.rs"]
mod snapshot;

fn main() -> Result<(), voxoct_core::OctreeError> {
    let reps: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let tris = snapshot::triangles();
    let mut leaves = 0;
    for _ in 0..reps {
        let mut tree = Octree::new(snapshot::root_min(), 1.0, 0.001)?;
        tree.insert_all(std::hint::black_box(&tris));
        leaves = tree.leaf_count();
    }
    println!("{} triangles x {reps}: {leaves} leaves", tris.len());
    Ok(())
}
