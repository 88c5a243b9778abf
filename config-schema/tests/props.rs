//! Property tests of the blob: generated valid tables round-trip, and no byte string makes
//! `decode` panic or accept an invalid table.

mod strategy;

use config_schema::blob::{HEADER_LEN, TRAILER_LEN};
use config_schema::{decode, validate, DecodeError};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use proptest::test_runner::TestRunner;
use strategy::{blob, field_mutated_blob, interpreter_safe, mutated_blob, seal, table};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// (a) Every generated table is valid and `decode(encode(t)) == t`, generation included.
    #[test]
    fn valid_tables_round_trip(t in table()) {
        prop_assert_eq!(validate(&t), Ok(()));
        prop_assert_eq!(interpreter_safe(&t), Ok(()));
        let b = blob(&t);
        prop_assert_eq!(decode(&b), Ok(t.clone()));
        // Encoding is deterministic.
        prop_assert_eq!(blob(&t), b);
    }

    /// Any single-bit flip of a valid blob is rejected (envelope checks or CRC-32).
    #[test]
    fn a_flipped_bit_is_always_detected(t in table(), at in any::<usize>(), bit in 0u8..8) {
        let mut b = blob(&t);
        let at = at % b.len();
        b[at] ^= 1 << bit;
        prop_assert!(decode(&b).is_err());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// (b) Random byte strings never panic `decode`.
    #[test]
    fn random_bytes_never_panic(bytes in vec(any::<u8>(), 0..200)) {
        let _ = decode(&bytes);
    }

    /// Random payloads in a correct envelope reach the payload parser; they never panic,
    /// and whatever decodes is safe to interpret.
    #[test]
    fn random_payloads_never_panic(payload in vec(prop_oneof![0u8..4, any::<u8>()], 0..160)) {
        if let Ok(t) = decode(&seal(&payload, 1)) {
            prop_assert_eq!(interpreter_safe(&t), Ok(()));
        }
    }

    /// Mutated valid blobs (bit flips, byte sets, truncations, splices, copies in the payload,
    /// length and CRC recomputed) never panic `decode`; whatever decodes is safe to
    /// interpret and round-trips.
    #[test]
    fn mutated_blobs_never_panic(b in mutated_blob()) {
        match decode(&b) {
            Ok(t) => {
                // Checked by an oracle independent of `validate`.
                prop_assert_eq!(interpreter_safe(&t), Ok(()));
                prop_assert_eq!(decode(&blob(&t)), Ok(t));
            }
            Err(e) => {
                // The envelope is correct by construction: only the payload can be wrong.
                prop_assert!(
                    matches!(
                        e,
                        DecodeError::Payload(_)
                            | DecodeError::TrailingBytes(_)
                            | DecodeError::Invalid(_)
                    ),
                    "{:?}",
                    e
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// Tables mutated field by field (out-of-range references, counts, levels, ops) always
    /// parse: the validator refuses them or they are safe to interpret, and they round-trip.
    #[test]
    fn field_mutated_tables_are_refused_by_the_validator_or_safe(b in field_mutated_blob()) {
        if let Some(b) = b {
            match decode(&b) {
                Ok(t) => {
                    prop_assert_eq!(interpreter_safe(&t), Ok(()));
                    prop_assert_eq!(decode(&blob(&t)), Ok(t));
                }
                Err(e) => prop_assert!(matches!(e, DecodeError::Invalid(_)), "{:?}", e),
            }
        }
    }
}

/// The field mutations reach the validator (the bit mutations above mostly stop in the
/// parser): count, over a fixed-seed sample, how many it refuses and how many decode.
#[test]
fn field_mutations_reach_the_validator() {
    let mut runner = TestRunner::deterministic();
    let strategy = field_mutated_blob();
    let (mut none, mut invalid, mut ok) = (0, 0, 0);
    let n = 2000;
    for _ in 0..n {
        match strategy.new_tree(&mut runner).unwrap().current() {
            None => none += 1,
            Some(b) => match decode(&b) {
                Ok(t) => {
                    assert_eq!(interpreter_safe(&t), Ok(()));
                    ok += 1
                }
                Err(DecodeError::Invalid(_)) => invalid += 1,
                Err(e) => panic!("a table's blob does not parse: {e:?}"),
            },
        }
    }
    println!("of {n} field-mutated tables: {none} no table or no blob, {invalid} refused by the validator, {ok} decode");
    assert!(invalid >= n / 4, "validator: {invalid}");
    assert!(ok >= n / 20, "decoded: {ok}");
}

/// The mutation property is only worth something if its mutations reach every stage: count,
/// over a fixed-seed sample, how many blobs fail in the parser, fail in the validator, and
/// decode.
#[test]
fn mutations_reach_the_parser_the_validator_and_the_interpreter() {
    let mut runner = TestRunner::deterministic();
    let strategy = mutated_blob();
    let (mut postcard, mut invalid, mut ok) = (0, 0, 0);
    let n = 2000;
    for _ in 0..n {
        let b = strategy.new_tree(&mut runner).unwrap().current();
        assert!(b.len() >= HEADER_LEN + TRAILER_LEN);
        match decode(&b) {
            Ok(t) => {
                assert_eq!(interpreter_safe(&t), Ok(()));
                ok += 1
            }
            Err(DecodeError::Invalid(_)) => invalid += 1,
            Err(DecodeError::Payload(_) | DecodeError::TrailingBytes(_)) => postcard += 1,
            Err(e) => panic!("envelope error on a resealed blob: {e:?}"),
        }
    }
    println!("of {n} mutated blobs: {postcard} rejected by the parser, {invalid} by the validator, {ok} decode");
    assert!(postcard >= n / 10, "parser: {postcard}");
    // The packed payload has fewer invalid tables to reach: a reference is as
    // wide as its count, so most out-of-range values cannot be written at all, and a
    // mutated flag or count shifts every field after it, which the parser mostly refuses
    // (about 5 % reach the validator; over 10 % did under postcard's byte-aligned fields).
    assert!(invalid >= n / 25, "validator: {invalid}");
    assert!(ok >= n / 20, "decoded: {ok}");
}
