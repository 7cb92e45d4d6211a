//! Progress of the long operations on large meshes, for a caller that shows it.
//!
//! Reading a mesh ([`crate::object::Object::from_file_with`]), validating it and building
//! its facets ([`crate::object::Object::from_polygons_with`]), and building a grasp problem
//! ([`crate::quality::GraspProblem::new_with`]) take time in proportion to the mesh's size:
//! seconds per million triangles (BENCHMARKS.md). They report, through a [`Progress`], each
//! [`Stage`] as it starts (`done = 0`), now and then as it goes, and as it ends
//! (`done = total`). This crate draws nothing and keeps no time: the caller decides what to
//! show, and when (the CLI: a bar on a terminal, plain lines otherwise, after a second).

/// A stage of a long operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Stage {
    /// Reading the file's triangles or polygons (`total`: the count a binary STL header
    /// states, else 0 until the end: unknown).
    Read,
    /// Welding equal vertices (`total`: the vertices read).
    Weld,
    /// Checking the faces and their edges: closed, manifold, consistently oriented (`total`:
    /// the faces).
    Check,
    /// Face geometry, mass properties and the facets' neighbourhood graph (`total`: the
    /// faces).
    Facets,
    /// Cutting the planar section (`total`: the faces).
    Section,
    /// Object wrenches of the facets and primitive wrenches of the candidates (`total`:
    /// facets plus candidates).
    Wrenches,
    /// The tree of bounding ellipsoids over the object wrenches (`total`: the object
    /// wrenches).
    SupportTree,
}

impl Stage {
    /// What the stage does, for messages ("reading the mesh").
    pub fn describe(self) -> &'static str {
        match self {
            Stage::Read => "reading the mesh",
            Stage::Weld => "welding vertices",
            Stage::Check => "checking faces and edges",
            Stage::Facets => "facets and their neighbours",
            Stage::Section => "cutting the section",
            Stage::Wrenches => "object and contact wrenches",
            Stage::SupportTree => "support tree over the object wrenches",
        }
    }

    /// What `done` and `total` count ("faces": an STL file's triangles, an OBJ file's
    /// polygons).
    pub fn unit(self) -> &'static str {
        match self {
            Stage::Weld => "vertices",
            Stage::Read | Stage::Check | Stage::Facets | Stage::Section => "faces",
            Stage::Wrenches => "wrenches",
            Stage::SupportTree => "object wrenches",
        }
    }
}

/// Receives progress reports; any `FnMut(Stage, usize, usize)` is one.
pub trait Progress {
    /// `done` of `total` items of `stage` are done (`total` 0: not known yet). Called with
    /// `done = 0` when the stage starts, and with `done = total` when it ends.
    fn report(&mut self, stage: Stage, done: usize, total: usize);
}

impl<F: FnMut(Stage, usize, usize)> Progress for F {
    fn report(&mut self, stage: Stage, done: usize, total: usize) {
        self(stage, done, total)
    }
}

/// Reports nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn report(&mut self, _: Stage, _: usize, _: usize) {}
}

/// Items between two reports inside a stage (a power of two: `i & (EVERY - 1) == 0`).
pub(crate) const EVERY: usize = 1 << 16;

/// Reports item `i` of `total` if it is a multiple of [`EVERY`] (and not the first: the
/// stage's start is reported by the caller).
#[inline]
pub(crate) fn tick(progress: &mut dyn Progress, stage: Stage, i: usize, total: usize) {
    if i != 0 && i & (EVERY - 1) == 0 {
        progress.report(stage, i, total);
    }
}
