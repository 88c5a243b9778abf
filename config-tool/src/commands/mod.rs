//! One function per command.

pub mod alarms;
pub mod demo;
pub mod export;
pub mod keys;
pub mod matrix;
pub mod offline;
pub mod outputs;
pub mod panel;
pub mod radio;
