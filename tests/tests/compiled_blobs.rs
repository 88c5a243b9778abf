//! The blobs of every robot of `robot-configs/`, role by role: each in the compact form,
//! and with any one field of its table at an edge value its blob decodes to that table
//! exactly or the validator refuses it (the parser never refuses what the encoder wrote).

use config_schema::pack;
use test_tables::robots::{compiled, robots};
use test_tables::{edge_sweep, Sweep};

#[test]
fn every_compiled_role_with_a_field_at_an_edge_value_decodes_exactly_or_is_refused() {
    let mut total = Sweep::default();
    let mut roles = 0;
    for path in robots() {
        let (_, c) = compiled(&path);
        for t in &c.tables {
            let role = format!("{}: {}", path.display(), t.header.role);
            assert!(pack::is_compact(t), "{role}: not in the compact form");
            let sweep = edge_sweep(t);
            assert!(sweep.exact > 0 && sweep.refused > 0, "{role}: {sweep:?}");
            total.exact += sweep.exact;
            total.refused += sweep.refused;
            roles += 1;
        }
    }
    println!("{roles} roles: {total:?}");
    assert!(roles >= 20, "{roles} roles");
}
