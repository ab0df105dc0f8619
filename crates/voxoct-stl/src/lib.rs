//! voxoct-stl (under construction).
