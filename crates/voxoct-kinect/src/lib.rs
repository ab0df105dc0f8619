//! voxoct-kinect (under construction).
