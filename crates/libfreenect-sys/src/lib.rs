//! Raw FFI bindings to the system libfreenect (under construction).
