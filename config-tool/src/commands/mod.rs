//! One function per command.

pub mod demo;
pub mod offline;
pub mod radio;
