//! voxoct-mesh (under construction).
