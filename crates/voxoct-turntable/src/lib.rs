//! voxoct-turntable (under construction).
