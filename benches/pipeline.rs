//! Pipeline bench (placeholder).
fn main() {}
