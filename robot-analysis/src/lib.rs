//! What a compiled robot will do, before it is pushed: the compiled blobs run on the node
//! firmware's own interpreter (`node_fw::sim`, virtual time) with the plant model of
//! `node_fw::cylinder`.
//!
//! - [`sim`]: the world of a compiled robot, cycles checked against the sequence.
//! - [`sorter`]: a sorting station sorting its ball feed, and the bins the reference
//!   semantics gives.
//! - [`inject`]: faults injected into the simulation, their detection and what followed.
//! - [`timeline`]: a state-timing diagram (SVG) of a run.
//! - [`petri`]: the reference modular logic controller of control functions (the
//!   paper's matrix algebra), what their compiled charts are tested against.
//! - [`verify`]: every reachable state of charts, plant and radio; the properties.

pub mod automata;
pub mod inject;
pub mod petri;
pub mod sim;
pub mod sorter;
pub mod timeline;
pub mod verify;
