//! A role name read from bytes: UTF-8 checked char by char.
//!
//! What `core::str::from_utf8` accepts, and nothing else (a proptest and every sequence of
//! up to three bytes hold the two equal): shortest forms only, no surrogates, nothing past
//! U+10FFFF. The node reads role names only here; `from_utf8` with its fast ASCII path and
//! its 256-byte width table cost 624 B of flash on the nRF52840.

use heapless::String;

use crate::limits::MAX_ROLE_NAME;

/// Why bytes are not a role name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NameError {
    /// The bytes are not UTF-8 (whatever their length).
    Utf8,
    /// UTF-8, but longer than `MAX_ROLE_NAME` bytes.
    Capacity,
}

/// The char that starts at `bytes[*at]`, `*at` moved past it; `None` if the bytes there are
/// not one char's UTF-8.
fn next_char(bytes: &[u8], at: &mut usize) -> Option<char> {
    let first = u32::from(*bytes.get(*at)?);
    let (len, least, mut c) = match first {
        0x00..=0x7F => (1, 0, first),
        0xC0..=0xDF => (2, 0x80, first & 0x1F),
        0xE0..=0xEF => (3, 0x800, first & 0x0F),
        0xF0..=0xF7 => (4, 0x1_0000, first & 0x07),
        _ => return None,
    };
    for k in 1..len {
        let b = u32::from(*bytes.get(*at + k)?);
        if b & 0xC0 != 0x80 {
            return None;
        }
        c = (c << 6) | (b & 0x3F);
    }
    if c < least {
        return None; // an overlong form
    }
    *at += len;
    char::from_u32(c) // no surrogates, nothing past U+10FFFF
}

/// `bytes` as a role name: `Utf8` if they are not UTF-8 anywhere, else `Capacity` if they
/// are longer than `MAX_ROLE_NAME`.
#[inline(never)]
pub fn role_name(bytes: &[u8]) -> Result<String<MAX_ROLE_NAME>, NameError> {
    let mut name = String::new();
    let mut full = false;
    let mut at = 0;
    while at < bytes.len() {
        let c = next_char(bytes, &mut at).ok_or(NameError::Utf8)?;
        full |= name.push(c).is_err();
    }
    if full {
        return Err(NameError::Capacity);
    }
    Ok(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn core_says(bytes: &[u8]) -> Result<String<MAX_ROLE_NAME>, NameError> {
        let text = core::str::from_utf8(bytes).map_err(|_| NameError::Utf8)?;
        let mut name = String::new();
        name.push_str(text).map_err(|_| NameError::Capacity)?;
        Ok(name)
    }

    #[test]
    fn every_sequence_of_up_to_three_bytes_reads_as_core_reads_it() {
        assert_eq!(role_name(&[]), core_says(&[]));
        for a in 0..=255u8 {
            assert_eq!(role_name(&[a]), core_says(&[a]), "{a:02x}");
            for b in 0..=255u8 {
                assert_eq!(role_name(&[a, b]), core_says(&[a, b]), "{a:02x} {b:02x}");
                for c in [
                    0x00, 0x7F, 0x80, 0x8F, 0x90, 0x9F, 0xA0, 0xBF, 0xC0, 0xF4, 0xFF,
                ] {
                    let s = [a, b, c];
                    assert_eq!(role_name(&s), core_says(&s), "{s:02x?}");
                }
            }
        }
    }

    #[test]
    fn four_byte_forms_at_their_edges() {
        for s in [
            [0xF0, 0x90, 0x80, 0x80],
            [0xF0, 0x8F, 0xBF, 0xBF],
            [0xF4, 0x8F, 0xBF, 0xBF],
            [0xF4, 0x90, 0x80, 0x80],
            [0xF5, 0x80, 0x80, 0x80],
            [0xF7, 0xBF, 0xBF, 0xBF],
            [0xED, 0x9F, 0xBF, 0x41],
            [0xED, 0xA0, 0x80, 0x41],
        ] {
            assert_eq!(role_name(&s), core_says(&s), "{s:02x?}");
        }
    }

    proptest! {
        #[test]
        fn any_bytes_read_as_core_reads_them(bytes in proptest::collection::vec(any::<u8>(), 0..20)) {
            prop_assert_eq!(role_name(&bytes), core_says(&bytes));
        }

        #[test]
        fn any_text_reads_as_itself(text in "\\PC{0,8}") {
            prop_assert_eq!(role_name(text.as_bytes()), core_says(text.as_bytes()));
        }
    }
}
