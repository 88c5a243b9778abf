//! One function per command.

pub mod demo;
pub mod keys;
pub mod offline;
pub mod radio;
