//! Test support of the IEC 61499 export tests.

pub mod schema;
