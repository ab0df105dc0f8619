//! The error type of voxoct-core.

use std::fmt;

use crate::geometry::{Aabb, Real};

/// What can go wrong when building or combining octrees.
///
/// Every variant names the offending value.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum OctreeError {
    /// An argument is out of its domain: NaN or infinite, or a length that is zero or
    /// negative. `name` is the parameter as the signature spells it (`"root_m"`,
    /// `"leaf_m"`, `"min.y"`, `"bounds.max.x"`, or `"min + root_m"` when the root's far
    /// corner overflows); the same pattern as `voxoct_mesh::MeshError::InvalidArgument`
    /// and `voxoct_stl::StlError::InvalidArgument`.
    ///
    /// How to fix: pass finite metres (the root edge and the leaf size are lengths, e.g.
    /// `1.0` and `0.001`); check the scan's clip box and rig parameters.
    InvalidArgument {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What the value must be.
        reason: &'static str,
    },
    /// The leaf size exceeds the root edge.
    ///
    /// How to fix: use a root at least as large as one leaf (usually much larger: the
    /// whole object must fit in the root).
    LeafLargerThanRoot {
        /// Requested leaf size, metres.
        leaf_m: Real,
        /// Root edge, metres.
        root_m: Real,
    },
    /// The leaf size needs more subdivision levels than the octree supports.
    ///
    /// How to fix: use a larger leaf or a smaller root; `edge / leaf_size` must stay
    /// below `2^MAX_DEPTH` ([`crate::MAX_DEPTH`]).
    TooDeep {
        /// Depth the leaf size would need.
        depth: u32,
        /// The supported maximum.
        max: u32,
    },
    /// The leaves would be too small for `f32` coordinates this far from the origin:
    /// neighbouring grid planes would round together.
    ///
    /// How to fix: move the root closer to the origin (work in a local frame) or use
    /// a larger leaf; leaves must be at least `magnitude / 2^20`.
    LeafBelowPrecision {
        /// The real leaf edge, metres.
        leaf_edge: Real,
        /// The largest absolute root coordinate, metres.
        magnitude: Real,
    },
    /// The bounds given to [`Octree::enclosing`](crate::Octree::enclosing) have
    /// `min > max` on an axis.
    ///
    /// How to fix: build the bounds from data (e.g. fold `Triangle::aabb`) and skip the
    /// call when there is no data.
    InvalidBounds {
        /// The axis, `'x'`, `'y'` or `'z'`.
        axis: char,
        /// Minimum on that axis.
        min: Real,
        /// Maximum on that axis.
        max: Real,
    },
    /// Two octrees to merge do not share the same root box.
    ///
    /// How to fix: build both with the same `min` and `edge`.
    RootMismatch {
        /// Root of the octree merged into.
        this: Aabb,
        /// Root of the other octree.
        other: Aabb,
    },
    /// Two octrees to merge do not have the same depth.
    ///
    /// How to fix: build both with leaf sizes that give the same depth (the same
    /// leaf size is simplest).
    DepthMismatch {
        /// Depth of the octree merged into.
        this: u32,
        /// Depth of the other octree.
        other: u32,
    },
}

impl fmt::Display for OctreeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidArgument {
                name,
                value,
                reason,
            } => write!(f, "invalid `{name}` = {value}: {reason}"),
            Self::LeafLargerThanRoot { leaf_m, root_m } => write!(
                f,
                "leaf size {leaf_m} m is larger than the root edge {root_m} m"
            ),
            Self::TooDeep { depth, max } => write!(
                f,
                "the leaf size needs depth {depth}, more than the supported {max}"
            ),
            Self::LeafBelowPrecision {
                leaf_edge,
                magnitude,
            } => write!(
                f,
                "leaf edge {leaf_edge} m is below f32 precision at coordinates of {magnitude} m"
            ),
            Self::InvalidBounds { axis, min, max } => {
                write!(f, "bounds have min {min} > max {max} on axis {axis}")
            }
            Self::RootMismatch { this, other } => write!(
                f,
                "octree roots differ: {:?}..{:?} vs {:?}..{:?}",
                this.min, this.max, other.min, other.max
            ),
            Self::DepthMismatch { this, other } => {
                write!(f, "octree depths differ: {this} vs {other}")
            }
        }
    }
}

impl std::error::Error for OctreeError {}

impl OctreeError {
    /// [`OctreeError::InvalidArgument`] for a NaN or infinite value.
    pub(crate) fn not_finite(name: &'static str, value: Real) -> Self {
        Self::InvalidArgument {
            name,
            value: f64::from(value),
            reason: "must be finite",
        }
    }

    /// [`OctreeError::InvalidArgument`] for a length that is zero or negative.
    pub(crate) fn not_positive(name: &'static str, value: Real) -> Self {
        Self::InvalidArgument {
            name,
            value: f64::from(value),
            reason: "must be positive (a length in metres)",
        }
    }
}
