//! Tests of the frame security codec: literal bytes, the IEEE 802.15.4 Annex C vectors, a
//! cross-check against OpenSSL's CCM, and mutated and random frames.

extern crate std;

use std::vec::Vec;

use aes::Aes128;

use super::*;
use crate::wire::mac::{emit_data, FCS, MAX_PAYLOAD};

/// The Annex C key and source: `C0 C1 .. CF`, extended address `ACDE480000000001`.
const ANNEX_KEY: [u8; 16] = [
    0xC0, 0xC1, 0xC2, 0xC3, 0xC4, 0xC5, 0xC6, 0xC7, 0xC8, 0xC9, 0xCA, 0xCB, 0xCC, 0xCD, 0xCE, 0xCF,
];
const ANNEX_SRC: [u8; 8] = [0xAC, 0xDE, 0x48, 0x00, 0x00, 0x00, 0x00, 0x01];

// IEEE 802.15.4-2006 Annex C.2 (the same frames are Annex C.2 of 802.15.4-2015), frame
// counter 5, key id mode 0. The bytes as reproduced in OpenThread's
// `tests/unit/test_aes.cpp` and Tock's AES-CCM* capsule test, which agree.

/// C.2.1: beacon frame, MIC-64. a data: the whole unsecured frame (header 13, aux 5 at 13,
/// beacon payload 8); then the MIC.
const C21_FRAME: [u8; 26] = [
    0x08, 0xD0, 0x84, 0x21, 0x43, 0x01, 0x00, 0x00, 0x00, 0x00, 0x48, 0xDE, 0xAC, 0x02, 0x05, 0x00,
    0x00, 0x00, 0x55, 0xCF, 0x00, 0x00, 0x51, 0x52, 0x53, 0x54,
];
const C21_MIC: [u8; 8] = [0x22, 0x3B, 0xC1, 0xEC, 0x84, 0x1A, 0xB5, 0x53];
const C21_NONCE: [u8; 13] = [
    0xAC, 0xDE, 0x48, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x02,
];

/// C.2.2: data frame, ENC (level 4, no MIC). Header 21, aux 5 at 21, payload "abcd".
const C22_FRAME: [u8; 30] = [
    0x69, 0xDC, 0x84, 0x21, 0x43, 0x02, 0x00, 0x00, 0x00, 0x00, 0x48, 0xDE, 0xAC, 0x01, 0x00, 0x00,
    0x00, 0x00, 0x48, 0xDE, 0xAC, 0x04, 0x05, 0x00, 0x00, 0x00, 0x61, 0x62, 0x63, 0x64,
];
const C22_CIPHERTEXT: [u8; 4] = [0xD4, 0x3E, 0x02, 0x2B];
const C22_NONCE: [u8; 13] = [
    0xAC, 0xDE, 0x48, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x04,
];

/// C.2.3: MAC command frame, ENC-MIC-64. Header 23, aux 5 at 23, command id (a data),
/// command payload 0xCE (m data).
const C23_FRAME: [u8; 30] = [
    0x2B, 0xDC, 0x84, 0x21, 0x43, 0x02, 0x00, 0x00, 0x00, 0x00, 0x48, 0xDE, 0xAC, 0xFF, 0xFF, 0x01,
    0x00, 0x00, 0x00, 0x00, 0x48, 0xDE, 0xAC, 0x06, 0x05, 0x00, 0x00, 0x00, 0x01, 0xCE,
];
const C23_SECURED_TAIL: [u8; 9] = [0xD8, 0x4F, 0xDE, 0x52, 0x90, 0x61, 0xF9, 0xC6, 0xF1];
const C23_NONCE: [u8; 13] = [
    0xAC, 0xDE, 0x48, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x06,
];

#[test]
fn annex_c_nonces() {
    assert_eq!(nonce(&ANNEX_SRC, 5, SecurityLevel::Mic64), C21_NONCE);
    assert_eq!(nonce(&ANNEX_SRC, 5, SecurityLevel::Enc), C22_NONCE);
    assert_eq!(nonce(&ANNEX_SRC, 5, SecurityLevel::EncMic64), C23_NONCE);
}

#[test]
fn annex_c_aux_headers_parse() {
    for (frame, at, level) in [
        (&C21_FRAME[..], 13, SecurityLevel::Mic64),
        (&C22_FRAME[..], 21, SecurityLevel::Enc),
        (&C23_FRAME[..], 23, SecurityLevel::EncMic64),
    ] {
        let view = AuxHeader::new_checked(&frame[at..]).unwrap();
        assert_eq!(view.header_len(), 5);
        assert_eq!(
            AuxRepr::parse(&view),
            AuxRepr {
                level,
                key_id: KeyId::Implicit,
                frame_counter: 5
            }
        );
    }
}

#[test]
fn annex_c_2_1_beacon_mic_64() {
    let mut mic = [0u8; 8];
    seal(
        &ANNEX_KEY,
        &C21_NONCE,
        SecurityLevel::Mic64,
        &C21_FRAME,
        &mut [],
        &mut mic,
    )
    .unwrap();
    assert_eq!(mic, C21_MIC);
    let ok = unseal(
        &ANNEX_KEY,
        &C21_NONCE,
        SecurityLevel::Mic64,
        &C21_FRAME,
        &mut [],
        &C21_MIC,
    );
    assert_eq!(ok, Ok(()));
    let mut bad = C21_MIC;
    bad[7] ^= 0x80;
    let refused = unseal(
        &ANNEX_KEY,
        &C21_NONCE,
        SecurityLevel::Mic64,
        &C21_FRAME,
        &mut [],
        &bad,
    );
    assert_eq!(refused, Err(SecError::BadMic));
}

#[test]
fn annex_c_2_2_data_frame_encryption_keystream() {
    // Level 4 has no MIC, so `secure`/`open` refuse it; its vector still checks the nonce
    // and CCM*'s counter blocks A_i = flags (L - 1 = 1) || nonce || i, from i = 1.
    use ctr::cipher::{KeyIvInit, StreamCipher};
    let mut a1 = [0u8; 16];
    a1[0] = 0x01;
    a1[1..14].copy_from_slice(&nonce(&ANNEX_SRC, 5, SecurityLevel::Enc));
    a1[15] = 0x01;
    let mut payload = [0u8; 4];
    payload.copy_from_slice(&C22_FRAME[26..]);
    let mut ctr = ctr::Ctr128BE::<Aes128>::new(&ANNEX_KEY.into(), &a1.into());
    ctr.apply_keystream(&mut payload);
    assert_eq!(payload, C22_CIPHERTEXT);
}

#[test]
fn annex_c_2_3_command_frame_enc_mic_64() {
    let (a, m) = C23_FRAME.split_at(29);
    let mut m = [m[0]];
    let mut mic = [0u8; 8];
    seal(
        &ANNEX_KEY,
        &C23_NONCE,
        SecurityLevel::EncMic64,
        a,
        &mut m,
        &mut mic,
    )
    .unwrap();
    assert_eq!(m[0], C23_SECURED_TAIL[0]);
    assert_eq!(mic, C23_SECURED_TAIL[1..]);
    unseal(
        &ANNEX_KEY,
        &C23_NONCE,
        SecurityLevel::EncMic64,
        a,
        &mut m,
        &mic,
    )
    .unwrap();
    assert_eq!(m, [0xCE]);
    // A flipped bit in the a data: refused, and the decrypted byte is not left behind.
    let mut a2 = [0u8; 29];
    a2.copy_from_slice(a);
    a2[2] ^= 0x01;
    let mut m = [C23_SECURED_TAIL[0]];
    let refused = unseal(
        &ANNEX_KEY,
        &C23_NONCE,
        SecurityLevel::EncMic64,
        &a2,
        &mut m,
        &mic,
    );
    assert_eq!(refused, Err(SecError::BadMic));
    assert_eq!(m, [0]);
}

#[test]
fn aux_header_bytes_per_key_id_mode() {
    let cases: [(AuxRepr, &[u8]); 4] = [
        (
            AuxRepr {
                level: SecurityLevel::Mic32,
                key_id: KeyId::Implicit,
                frame_counter: 0x0403_0201,
            },
            &[0x01, 0x01, 0x02, 0x03, 0x04],
        ),
        (AuxRepr::new(0x07, 5), &[0x0E, 0x05, 0x00, 0x00, 0x00, 0x07]),
        (
            AuxRepr {
                level: SecurityLevel::EncMic128,
                key_id: KeyId::Source4 {
                    source: [0xA1, 0xA2, 0xA3, 0xA4],
                    index: 0x09,
                },
                frame_counter: 1,
            },
            &[0x17, 0x01, 0, 0, 0, 0xA1, 0xA2, 0xA3, 0xA4, 0x09],
        ),
        (
            AuxRepr {
                level: SecurityLevel::EncMic32,
                key_id: KeyId::Source8 {
                    source: [1, 2, 3, 4, 5, 6, 7, 8],
                    index: 0xFF,
                },
                frame_counter: u32::MAX,
            },
            &[0x1D, 0xFF, 0xFF, 0xFF, 0xFF, 1, 2, 3, 4, 5, 6, 7, 8, 0xFF],
        ),
    ];
    for (repr, bytes) in cases {
        let mut buf = [0u8; 16];
        assert_eq!(repr.emit(&mut buf), Ok(bytes.len()));
        assert_eq!(&buf[..bytes.len()], bytes);
        assert_eq!(repr.buffer_len(), bytes.len());
        let view = AuxHeader::new_checked(bytes).unwrap();
        assert_eq!(view.header_len(), bytes.len());
        assert_eq!(view.key_index(), repr.key_id.index());
        assert_eq!(AuxRepr::parse(&view), repr);
        // One byte short of its key identifier: malformed.
        assert_eq!(
            AuxHeader::new_checked(&bytes[..bytes.len() - 1]),
            Err(SecError::Malformed)
        );
        let mut small = [0u8; 16];
        assert_eq!(
            repr.emit(&mut small[..bytes.len() - 1]),
            Err(SecError::NoRoom)
        );
    }
    assert_eq!(AuxHeader::new_checked(&[][..]), Err(SecError::Malformed));
    // Frame counter suppression, ASN in nonce, reserved: not in 2006 frames.
    for bit in [0x20, 0x40, 0x80] {
        assert_eq!(
            AuxHeader::new_checked(&[0x0E | bit, 5, 0, 0, 0, 1][..]),
            Err(SecError::Malformed)
        );
    }
}

#[test]
fn levels() {
    let mics: Vec<usize> = SecurityLevel::ALL.iter().map(|l| l.mic_len()).collect();
    assert_eq!(mics, [0, 4, 8, 16, 0, 4, 8, 16]);
    for (i, level) in SecurityLevel::ALL.iter().enumerate() {
        assert_eq!(usize::from(level.bits()), i);
        assert_eq!(SecurityLevel::from_bits(level.bits()), *level);
        assert_eq!(level.encrypts(), i >= 4);
    }
    assert_eq!(SecurityLevel::default(), SecurityLevel::EncMic64);
}

#[test]
fn extended_address_of_a_short_address() {
    assert_eq!(
        ext_addr(0xBEEF, 0x0001),
        [0xBE, 0xEF, 0x00, 0xFF, 0xFE, 0x00, 0x00, 0x01]
    );
    assert_eq!(
        ext_addr(0x1234, 0xFFFE),
        [0x12, 0x34, 0x00, 0xFF, 0xFE, 0x00, 0xFF, 0xFE]
    );
}

fn header() -> Header {
    Header {
        seq: 0x2A,
        pan_id: 0xBEEF,
        dst: 0x0003,
        src: 0x0001,
        ack_request: true,
        secured: false,
    }
}

/// The lookup a node does: one key, the sender's address by the one mapping.
fn node_lookup(key: [u8; 16]) -> impl FnOnce(&Header, &AuxRepr) -> Option<([u8; 16], [u8; 8])> {
    move |h: &Header, _: &AuxRepr| Some((key, ext_addr(h.pan_id, h.src)))
}

/// Replaces the FCS of `psdu` after `body_len` bytes (a body edited by an attacker).
fn with_fcs(body: &[u8]) -> Vec<u8> {
    let mut v = body.to_vec();
    v.extend_from_slice(&FCS.checksum(body).to_le_bytes());
    v
}

#[test]
fn our_data_frame_bytes() {
    // Node 0x0001 on PAN 0xBEEF to node 0x0003, key index 7... here 1, counter 5, payload
    // "abcd". Ciphertext and MIC computed independently with OpenSSL (Python
    // `cryptography`'s AESCCM, tag 8, nonce BEEF00FFFE000001 00000005 06, a data = the
    // 15 header bytes below).
    let mut out = [0u8; MAX_PSDU];
    let n = secure(
        &header(),
        &AuxRepr::new(1, 5),
        &ANNEX_KEY,
        ext_addr(0xBEEF, 0x0001),
        b"abcd",
        &mut out,
    )
    .unwrap();
    let body: [u8; 27] = [
        0x69, 0x98, 0x2A, 0xEF, 0xBE, 0x03, 0x00, 0x01, 0x00, // FC 0x9869: security bit
        0x0E, 0x05, 0x00, 0x00, 0x00, 0x01, // ENC-MIC-64, key id mode 1, counter 5, index 1
        0x96, 0x4D, 0x92, 0x15, // "abcd" encrypted
        0x47, 0xB7, 0x89, 0xC4, 0xBA, 0x15, 0x1B, 0x52, // MIC-64
    ];
    assert_eq!(n, body.len() + 2);
    assert_eq!(&out[..n], with_fcs(&body).as_slice());
    let mut scratch = [0u8; MAX_PAYLOAD];
    let opened = open(&out[..n], node_lookup(ANNEX_KEY), &mut scratch).unwrap();
    assert_eq!(
        opened,
        Opened {
            header: Header {
                secured: true,
                ..header()
            },
            aux: AuxRepr::new(1, 5),
            payload: b"abcd",
        }
    );
}

#[test]
fn open_names_why_a_frame_is_refused() {
    let key = ANNEX_KEY;
    let src = ext_addr(0xBEEF, 0x0001);
    let mut psdu = [0u8; MAX_PSDU];
    let n = secure(
        &header(),
        &AuxRepr::new(1, 9),
        &key,
        src,
        b"START",
        &mut psdu,
    )
    .unwrap();
    let psdu = &psdu[..n];
    let mut scratch = [0u8; MAX_PAYLOAD];

    let mut plain = [0u8; MAX_PSDU];
    let m = emit_data(&header(), b"START", &mut plain).unwrap();
    assert_eq!(
        open(&plain[..m], node_lookup(key), &mut scratch),
        Err(SecError::NotSecured)
    );
    let mut ack = [0u8; 5];
    mac::emit_ack(1, false, &mut ack).unwrap();
    assert_eq!(
        open(&ack, node_lookup(key), &mut scratch),
        Err(SecError::Frame(FrameError::Unsupported))
    );
    let mut bad_fcs = psdu.to_vec();
    bad_fcs[n - 1] ^= 1;
    assert_eq!(
        open(&bad_fcs, node_lookup(key), &mut scratch),
        Err(SecError::Frame(FrameError::BadFcs))
    );
    assert_eq!(
        open(psdu, |_: &Header, _: &AuxRepr| None, &mut scratch),
        Err(SecError::UnknownKey)
    );
    let mut wrong = key;
    wrong[0] ^= 1;
    assert_eq!(
        open(psdu, node_lookup(wrong), &mut scratch),
        Err(SecError::BadMic)
    );
    // The right key but another sender's address in the nonce.
    assert_eq!(
        open(
            psdu,
            |_: &Header, _: &AuxRepr| Some((key, ext_addr(0xBEEF, 0x0002))),
            &mut scratch
        ),
        Err(SecError::BadMic)
    );
    assert_eq!(scratch, [0u8; MAX_PAYLOAD], "nothing unauthenticated left");
    assert_eq!(
        open(psdu, node_lookup(key), &mut scratch[..4]),
        Err(SecError::NoRoom)
    );
    // Security bit, then an aux header cut short / a frame shorter than its MIC.
    let sec_header = Header {
        secured: true,
        ..header()
    };
    for payload in [
        &[0x0E, 5, 0, 0, 0][..],
        &[0x0E, 5, 0, 0, 0, 1, 0xAA, 0xBB][..],
    ] {
        let m = emit_data(&sec_header, payload, &mut plain).unwrap();
        assert_eq!(
            open(&plain[..m], node_lookup(key), &mut scratch),
            Err(SecError::Malformed)
        );
    }
    // Levels 0 and 4, and counter 0xFFFFFFFF, whatever follows.
    for aux in [
        [0x08, 5, 0, 0, 0, 1],
        [0x0C, 5, 0, 0, 0, 1],
        [0x0E, 0xFF, 0xFF, 0xFF, 0xFF, 1],
    ] {
        let mut payload = aux.to_vec();
        payload.extend_from_slice(&[0u8; 16]);
        let m = emit_data(&sec_header, &payload, &mut plain).unwrap();
        let expect = if aux[1] == 0xFF {
            SecError::CounterExhausted
        } else {
            SecError::NoMic
        };
        assert_eq!(
            open(&plain[..m], node_lookup(key), &mut scratch),
            Err(expect)
        );
    }
}

#[test]
fn secure_refuses_what_could_not_be_opened() {
    let mut out = [0u8; MAX_PSDU];
    let src = ext_addr(0xBEEF, 1);
    for level in [SecurityLevel::None, SecurityLevel::Enc] {
        let aux = AuxRepr {
            level,
            ..AuxRepr::new(1, 1)
        };
        assert_eq!(
            secure(&header(), &aux, &ANNEX_KEY, src, b"x", &mut out),
            Err(SecError::NoMic)
        );
    }
    assert_eq!(
        secure(
            &header(),
            &AuxRepr::new(1, u32::MAX),
            &ANNEX_KEY,
            src,
            b"x",
            &mut out
        ),
        Err(SecError::CounterExhausted)
    );
    let max = [0x55u8; MAX_SECURED_PAYLOAD];
    assert_eq!(
        secure(
            &header(),
            &AuxRepr::new(1, 1),
            &ANNEX_KEY,
            src,
            &max,
            &mut out
        ),
        Ok(MAX_PSDU)
    );
    let over = [0x55u8; MAX_SECURED_PAYLOAD + 1];
    assert_eq!(
        secure(
            &header(),
            &AuxRepr::new(1, 1),
            &ANNEX_KEY,
            src,
            &over,
            &mut out
        ),
        Err(SecError::NoRoom)
    );
    assert_eq!(
        secure(
            &header(),
            &AuxRepr::new(1, 1),
            &ANNEX_KEY,
            src,
            b"x",
            &mut out[..25]
        ),
        Err(SecError::NoRoom)
    );
}

#[test]
fn bytes_added_per_frame() {
    use crate::wire::msg::{Message, CHUNK_DATA};
    assert_eq!(AuxRepr::new(1, 0).buffer_len(), AUX_LEN_KEY_INDEX);
    assert_eq!(DEFAULT_OVERHEAD, 14);
    assert_eq!(MAX_SECURED_PAYLOAD, 102);
    let event = Message::Event {
        epoch: 1,
        seq: 1,
        topic: 1,
    };
    let chunk = Message::ConfigChunk {
        generation: u32::MAX,
        offset: u16::MAX,
        data: &[0xAA; CHUNK_DATA],
    };
    let mut buf = [0u8; MAX_PAYLOAD];
    let event_len = postcard::to_slice(&event, &mut buf)
        .map(|b| b.len())
        .unwrap();
    let chunk_len = postcard::to_slice(&chunk, &mut buf)
        .map(|b| b.len())
        .unwrap();
    let plain = |n: usize| DATA_HEADER_LEN + n + FCS_LEN;
    std::println!("frame security, ENC-MIC-64 with a key index (the default):");
    std::println!(
        "  bytes added per frame: {DEFAULT_OVERHEAD} (aux header {AUX_LEN_KEY_INDEX}: control 1, \
         frame counter 4, key index 1; MIC 8)"
    );
    std::println!(
        "  largest payload: {MAX_PAYLOAD} -> {MAX_SECURED_PAYLOAD} bytes; airtime per added byte 32 us"
    );
    std::println!(
        "  event frame: {} -> {} bytes, {} -> {} us on air",
        plain(event_len),
        plain(event_len) + DEFAULT_OVERHEAD,
        mac::airtime_us(plain(event_len)),
        mac::airtime_us(plain(event_len) + DEFAULT_OVERHEAD)
    );
    std::println!(
        "  largest ConfigChunk ({CHUNK_DATA} data bytes): payload {chunk_len} bytes, {} the \
         secured room of {MAX_SECURED_PAYLOAD}",
        if chunk_len <= MAX_SECURED_PAYLOAD {
            "fits"
        } else {
            "does NOT fit"
        }
    );
}

mod props {
    use super::*;
    use proptest::prelude::*;

    /// AES-128-CCM by OpenSSL (the calls its manual gives for CCM).
    pub(super) fn openssl_ccm(
        key: &[u8],
        nonce: &[u8],
        aad: &[u8],
        data: &[u8],
        tag: &mut [u8],
    ) -> Result<Vec<u8>, openssl::error::ErrorStack> {
        use openssl::cipher::Cipher;
        use openssl::cipher_ctx::CipherCtx;
        let mut ctx = CipherCtx::new()?;
        ctx.encrypt_init(Some(Cipher::aes_128_ccm()), None, None)?;
        ctx.set_iv_length(nonce.len())?;
        ctx.set_tag_length(tag.len())?;
        ctx.encrypt_init(None, Some(key), Some(nonce))?;
        ctx.set_data_len(data.len())?;
        ctx.cipher_update(aad, None)?;
        let mut out = std::vec![0u8; data.len()];
        ctx.cipher_update(data, Some(&mut out))?;
        ctx.cipher_final(&mut [])?;
        ctx.tag(tag)?;
        Ok(out)
    }

    fn level() -> impl Strategy<Value = SecurityLevel> {
        prop::sample::select(
            &[
                SecurityLevel::Mic32,
                SecurityLevel::Mic64,
                SecurityLevel::Mic128,
                SecurityLevel::EncMic32,
                SecurityLevel::EncMic64,
                SecurityLevel::EncMic128,
            ][..],
        )
    }

    fn key_id() -> impl Strategy<Value = KeyId> {
        prop_oneof![
            Just(KeyId::Implicit),
            any::<u8>().prop_map(KeyId::Index),
            (any::<[u8; 4]>(), any::<u8>())
                .prop_map(|(source, index)| KeyId::Source4 { source, index }),
            (any::<[u8; 8]>(), any::<u8>())
                .prop_map(|(source, index)| KeyId::Source8 { source, index }),
        ]
    }

    fn aux() -> impl Strategy<Value = AuxRepr> {
        (level(), key_id(), 0..u32::MAX).prop_map(|(level, key_id, frame_counter)| AuxRepr {
            level,
            key_id,
            frame_counter,
        })
    }

    fn mac_header() -> impl Strategy<Value = Header> {
        (
            any::<u8>(),
            any::<u16>(),
            any::<u16>(),
            any::<u16>(),
            any::<bool>(),
        )
            .prop_map(|(seq, pan_id, dst, src, ack_request)| Header {
                seq,
                pan_id,
                dst,
                src,
                ack_request,
                secured: false,
            })
    }

    /// The frame as the standard builds it, written here without the codec: header and
    /// aux header bytes by hand, the nonce by hand, CCM by OpenSSL.
    fn reference(h: &Header, aux: &AuxRepr, key: &[u8; 16], payload: &[u8]) -> Vec<u8> {
        let fc: u16 = 0b001
            | 1 << 3
            | u16::from(h.ack_request) << 5
            | 1 << 6
            | 0b10 << 10
            | 0b01 << 12
            | 0b10 << 14;
        let mut f = Vec::new();
        f.extend_from_slice(&fc.to_le_bytes());
        f.push(h.seq);
        f.extend_from_slice(&h.pan_id.to_le_bytes());
        f.extend_from_slice(&h.dst.to_le_bytes());
        f.extend_from_slice(&h.src.to_le_bytes());
        let level = aux.level as u8;
        let (mode, id): (u8, Vec<u8>) = match aux.key_id {
            KeyId::Implicit => (0, Vec::new()),
            KeyId::Index(i) => (1, std::vec![i]),
            KeyId::Source4 { source, index } => (2, [&source[..], &[index]].concat()),
            KeyId::Source8 { source, index } => (3, [&source[..], &[index]].concat()),
        };
        f.push(level | mode << 3);
        f.extend_from_slice(&aux.frame_counter.to_le_bytes());
        f.extend_from_slice(&id);
        let mut nonce = Vec::new();
        nonce.extend_from_slice(&h.pan_id.to_be_bytes());
        nonce.extend_from_slice(&[0x00, 0xFF, 0xFE, 0x00]);
        nonce.extend_from_slice(&h.src.to_be_bytes());
        nonce.extend_from_slice(&aux.frame_counter.to_be_bytes());
        nonce.push(level);
        let mut tag = std::vec![0u8; [0, 4, 8, 16][usize::from(level & 3)]];
        if level & 4 != 0 {
            let ct = openssl_ccm(key, &nonce, &f, payload, &mut tag).unwrap();
            f.extend_from_slice(&ct);
        } else {
            f.extend_from_slice(payload);
            let ct = openssl_ccm(key, &nonce, &f, &[], &mut tag).unwrap();
            assert!(ct.is_empty());
        }
        f.extend_from_slice(&tag);
        let kermit = crc::Crc::<u16>::new(&crc::CRC_16_KERMIT);
        let fcs = kermit.checksum(&f);
        f.extend_from_slice(&fcs.to_le_bytes());
        f
    }

    fn secured() -> impl Strategy<Value = (Header, AuxRepr, [u8; 16], Vec<u8>)> {
        (mac_header(), aux(), any::<[u8; 16]>()).prop_flat_map(|(h, aux, key)| {
            let room = MAX_PAYLOAD - aux.buffer_len() - aux.level.mic_len();
            (
                Just(h),
                Just(aux),
                Just(key),
                proptest::collection::vec(any::<u8>(), 0..=room),
            )
        })
    }

    proptest! {
        /// `secure` writes the bytes OpenSSL's CCM makes of the standard's construction,
        /// and `open` takes OpenSSL's frame back to the payload.
        #[test]
        fn agrees_with_openssl((h, aux, key, payload) in secured()) {
            let mut out = [0u8; MAX_PSDU];
            let n = secure(&h, &aux, &key, ext_addr(h.pan_id, h.src), &payload, &mut out).unwrap();
            let expected = reference(&h, &aux, &key, &payload);
            prop_assert_eq!(&out[..n], expected.as_slice());
            let mut scratch = [0u8; MAX_PAYLOAD];
            let opened = open(&expected, node_lookup(key), &mut scratch).unwrap();
            prop_assert_eq!(opened.header, Header { secured: true, ..h });
            prop_assert_eq!(opened.aux, aux);
            prop_assert_eq!(opened.payload, payload.as_slice());
        }

        /// Random bytes, with or without a valid FCS and the security bit: never a panic,
        /// never accepted (the lookup hands out the key for anything).
        #[test]
        fn random_bytes_are_never_accepted(
            bytes in proptest::collection::vec(any::<u8>(), 0..140),
            fix_fcs in any::<bool>(),
        ) {
            let mut psdu = bytes.clone();
            if fix_fcs && psdu.len() >= 2 {
                psdu[0] |= 0x08;
                psdu.truncate(psdu.len() - 2);
                psdu = with_fcs(&psdu);
            }
            let mut scratch = [0u8; MAX_PAYLOAD];
            prop_assert!(open(&psdu, node_lookup([7; 16]), &mut scratch).is_err());
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        /// Every single bit flip (the FCS made right again, so the flip reaches CCM*), every
        /// truncation and extensions of a secured frame: never a panic, never accepted.
        #[test]
        fn mutated_frames_are_never_accepted(
            (h, aux, key, payload) in secured(),
            tail in proptest::collection::vec(any::<u8>(), 1..4),
        ) {
            let mut out = [0u8; MAX_PSDU];
            let n = secure(&h, &aux, &key, ext_addr(h.pan_id, h.src), &payload, &mut out).unwrap();
            let body = &out[..n - FCS_LEN];
            let mut scratch = [0u8; MAX_PAYLOAD];
            prop_assert!(open(&out[..n], node_lookup(key), &mut scratch).is_ok());
            for bit in 0..n * 8 {
                let mut m = out[..n].to_vec();
                m[bit / 8] ^= 1 << (bit % 8);
                prop_assert!(open(&m, node_lookup(key), &mut scratch).is_err(), "bit {}", bit);
                if bit / 8 < body.len() {
                    let refcs = with_fcs(&m[..n - FCS_LEN]);
                    let r = open(&refcs, node_lookup(key), &mut scratch);
                    prop_assert!(r.is_err(), "bit {} FCS fixed: {:?}", bit, r);
                }
            }
            for len in 0..body.len() {
                prop_assert!(open(&with_fcs(&body[..len]), node_lookup(key), &mut scratch).is_err());
                prop_assert!(open(&out[..len], node_lookup(key), &mut scratch).is_err());
            }
            for k in 1..=tail.len() {
                let longer = [body, &tail[..k]].concat();
                prop_assert!(open(&with_fcs(&longer), node_lookup(key), &mut scratch).is_err());
            }
        }
    }
}
/// The second implementation checked on the published vectors too.
#[test]
fn openssl_reproduces_annex_c() {
    let mut tag = [0u8; 8];
    let ct = props::openssl_ccm(
        &ANNEX_KEY,
        &C23_NONCE,
        &C23_FRAME[..29],
        &C23_FRAME[29..],
        &mut tag,
    )
    .unwrap();
    assert_eq!([&ct[..], &tag[..]].concat(), C23_SECURED_TAIL);
    let ct = props::openssl_ccm(&ANNEX_KEY, &C21_NONCE, &C21_FRAME, &[], &mut tag).unwrap();
    assert!(ct.is_empty());
    assert_eq!(tag, C21_MIC);
}

#[test]
fn a_receiver_that_requires_enc_mic_64_refuses_a_weaker_mic_before_looking_up_a_key() {
    let key = [0x42; 16];
    let mut scratch = [0u8; MAX_PSDU];
    for (level, ok) in [
        (SecurityLevel::Mic32, false),
        (SecurityLevel::EncMic32, false),
        (SecurityLevel::EncMic128, false),
        (SecurityLevel::EncMic64, true),
    ] {
        let aux = AuxRepr {
            level,
            ..AuxRepr::new(1, 9)
        };
        let mut out = [0u8; MAX_PSDU];
        let n = secure(
            &header(),
            &aux,
            &key,
            ext_addr(0xBEEF, 0x0001),
            b"START",
            &mut out,
        )
        .unwrap();
        let mut looked_up = false;
        let r = open_at(
            &out[..n],
            SecurityLevel::EncMic64,
            |h: &Header, a: &AuxRepr| {
                looked_up = true;
                node_lookup(key)(h, a)
            },
            &mut scratch,
        );
        if ok {
            assert_eq!(r.map(|o| o.payload.to_vec()), Ok(b"START".to_vec()));
        } else {
            assert_eq!(
                r.map(|_| ()),
                Err(SecError::Level {
                    got: level,
                    required: SecurityLevel::EncMic64
                }),
                "{level:?}"
            );
            assert!(!looked_up, "{level:?}: no key looked up");
        }
    }
}

/// The node's entry points (one CCM* instance, ENC-MIC-64 only) make and open exactly the
/// frames of the general ones: Annex C.2.3 and our literal data frame; any other level is
/// refused by name, on both sides.
#[test]
fn the_enc_mic_64_only_path_is_the_same_codec() {
    let (a, m) = C23_FRAME.split_at(29);
    let mut m = [m[0]];
    let mut mic = [0u8; 8];
    let level = SecurityLevel::EncMic64;
    seal_default::<SoftAes>(&ANNEX_KEY, &C23_NONCE, level, a, &mut m, &mut mic).unwrap();
    assert_eq!(m[0], C23_SECURED_TAIL[0]);
    assert_eq!(mic, C23_SECURED_TAIL[1..]);
    unseal_default::<SoftAes>(&ANNEX_KEY, &C23_NONCE, level, a, &mut m, &mic).unwrap();
    assert_eq!(m, [0xCE]);

    let mut general = [0u8; MAX_PSDU];
    let mut node = [0u8; MAX_PSDU];
    let src = ext_addr(0xBEEF, 0x0001);
    let aux = AuxRepr::new(1, 5);
    let n = secure(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut general).unwrap();
    let k = secure_default(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut node).unwrap();
    assert_eq!((k, &node[..k]), (n, &general[..n]));
    let mut scratch = [0u8; MAX_PAYLOAD];
    let opened = open_default(&node[..k], node_lookup(ANNEX_KEY), &mut scratch).unwrap();
    assert_eq!((opened.aux, opened.payload), (aux, &b"abcd"[..]));
    let mut flipped = node;
    flipped[16] ^= 0x01;
    let mut scratch = [0u8; MAX_PAYLOAD];
    let refused = open_default(
        &with_fcs(&flipped[..k - 2]),
        node_lookup(ANNEX_KEY),
        &mut scratch,
    );
    assert_eq!(refused, Err(SecError::BadMic));

    let mic32 = AuxRepr {
        level: SecurityLevel::EncMic32,
        ..aux
    };
    let refused = secure_default(&header(), &mic32, &ANNEX_KEY, src, b"abcd", &mut node);
    let want = SecError::Level {
        got: SecurityLevel::EncMic32,
        required: SecurityLevel::EncMic64,
    };
    assert_eq!(refused, Err(want));
    let n = secure(&header(), &mic32, &ANNEX_KEY, src, b"abcd", &mut general).unwrap();
    let mut scratch = [0u8; MAX_PAYLOAD];
    let refused = open_default(&general[..n], node_lookup(ANNEX_KEY), &mut scratch);
    assert_eq!(refused, Err(want));
}

/// A board's block cipher as the node path takes it: software AES underneath, counting the
/// blocks it encrypts, and failing the block numbered [`FAIL_AT`] (as the nRF52840's ECB
/// would on ERRORECB or a timeout).
struct BoardCipher {
    aes: SoftAes,
    blocks: core::cell::Cell<usize>,
    fail_at: usize,
}

std::thread_local! {
    /// The block (counted from 0 per key) a [`BoardCipher`] made on this thread fails.
    static FAIL_AT: core::cell::Cell<usize> = const { core::cell::Cell::new(usize::MAX) };
    /// Blocks encrypted by the [`BoardCipher`]s of this thread.
    static BLOCKS: core::cell::Cell<usize> = const { core::cell::Cell::new(0) };
}

impl BlockCipher for BoardCipher {
    fn new(key: &[u8; KEY_LEN]) -> Self {
        BoardCipher {
            aes: SoftAes::new(key),
            blocks: core::cell::Cell::new(0),
            fail_at: FAIL_AT.get(),
        }
    }

    fn encrypt(&self, block: &mut [u8; BLOCK_LEN]) -> Result<(), CipherFault> {
        let n = self.blocks.get();
        self.blocks.set(n + 1);
        BLOCKS.set(BLOCKS.get() + 1);
        if n == self.fail_at {
            *block = [0xEE; BLOCK_LEN];
            return Err(CipherFault);
        }
        self.aes.encrypt(block)
    }
}

/// The ENC-MIC-64 path with a block cipher of the caller's (a board's hardware AES) is
/// the same codec: Annex C.2.3 through it, and our data frame byte for byte as the
/// general path makes it, opened again; the cipher really is the one asked for.
#[test]
fn the_enc_mic_64_path_takes_a_board_block_cipher() {
    FAIL_AT.set(usize::MAX);
    BLOCKS.set(0);
    let (a, m) = C23_FRAME.split_at(29);
    let mut m = [m[0]];
    let mut mic = [0u8; 8];
    let level = SecurityLevel::EncMic64;
    seal_default::<BoardCipher>(&ANNEX_KEY, &C23_NONCE, level, a, &mut m, &mut mic).unwrap();
    assert_eq!(m[0], C23_SECURED_TAIL[0]);
    assert_eq!(mic, C23_SECURED_TAIL[1..]);
    // CBC-MAC: B0, two blocks of a (29 bytes + its 2-byte length), one of m; CTR: A0
    // (the MIC) and A1.
    assert_eq!(BLOCKS.get(), 6);
    unseal_default::<BoardCipher>(&ANNEX_KEY, &C23_NONCE, level, a, &mut m, &mic).unwrap();
    assert_eq!(m, [0xCE]);
    assert_eq!(BLOCKS.get(), 12);

    let mut general = [0u8; MAX_PSDU];
    let mut board = [0u8; MAX_PSDU];
    let src = ext_addr(0xBEEF, 0x0001);
    let aux = AuxRepr::new(1, 5);
    let n = secure(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut general).unwrap();
    let k =
        secure_default_with::<BoardCipher>(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut board)
            .unwrap();
    assert_eq!((k, &board[..k]), (n, &general[..n]));
    let mut scratch = [0u8; MAX_PAYLOAD];
    let opened =
        open_default_with::<BoardCipher, _>(&general[..n], node_lookup(ANNEX_KEY), &mut scratch)
            .unwrap();
    assert_eq!((opened.aux, opened.payload), (aux, &b"abcd"[..]));
}

/// A block the cipher fails, wherever it falls (CBC-MAC or CTR), is an error, never a
/// frame: nothing is emitted as sent, nothing opened, the scratch holds no plaintext.
#[test]
fn a_failed_block_is_an_error_not_a_frame() {
    let src = ext_addr(0xBEEF, 0x0001);
    let aux = AuxRepr::new(1, 5);
    let mut good = [0u8; MAX_PSDU];
    let n = secure(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut good).unwrap();
    // 9-byte header, 6-byte aux, 4-byte payload: B0, a (15 + 2 bytes: 2 blocks), m (1),
    // then A0 and A1.
    for fail_at in 0..6 {
        FAIL_AT.set(fail_at);
        let mut out = [0u8; MAX_PSDU];
        let sealed =
            secure_default_with::<BoardCipher>(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut out);
        assert_eq!(sealed, Err(SecError::Cipher), "seal, block {fail_at}");
        let mut scratch = [0x55u8; MAX_PAYLOAD];
        let opened =
            open_default_with::<BoardCipher, _>(&good[..n], node_lookup(ANNEX_KEY), &mut scratch);
        assert_eq!(opened, Err(SecError::Cipher), "open, block {fail_at}");
        assert_eq!(scratch[..4], [0; 4], "open, block {fail_at}");
    }
    FAIL_AT.set(6);
    let mut out = [0u8; MAX_PSDU];
    let sealed =
        secure_default_with::<BoardCipher>(&header(), &aux, &ANNEX_KEY, src, b"abcd", &mut out);
    assert_eq!(sealed, Ok(n));
    FAIL_AT.set(usize::MAX);
}

mod star_is_ccm {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The node's CCM* ([`star::ccm_star_64`]) is the `ccm` crate's at M = 8: the same
        /// ciphertext and MIC for any key, nonce and lengths of a (none too) and m (none,
        /// part of a block, several), and it opens what the crate sealed; a flipped MIC bit
        /// is refused with m zeroed.
        #[test]
        fn for_any_lengths(
            key in any::<[u8; 16]>(),
            nonce in any::<[u8; 13]>(),
            a in proptest::collection::vec(any::<u8>(), 0..48),
            m in proptest::collection::vec(any::<u8>(), 0..120),
            flip in 0usize..64,
        ) {
            let level = SecurityLevel::EncMic64;
            let (mut by_crate, mut crate_mic) = (m.clone(), [0u8; 8]);
            seal(&key, &nonce, level, &a, &mut by_crate, &mut crate_mic).unwrap();
            let (mut ours, mut mic) = (m.clone(), [0u8; 8]);
            seal_default::<SoftAes>(&key, &nonce, level, &a, &mut ours, &mut mic).unwrap();
            prop_assert_eq!(&ours, &by_crate);
            prop_assert_eq!(mic, crate_mic);
            // A board's cipher (the keystream one block after the other): the same
            // frame, and exactly CCM's blocks: B0, a with its length, m, and A0..An.
            FAIL_AT.set(usize::MAX);
            BLOCKS.set(0);
            let (mut by_board, mut board_mic) = (m.clone(), [0u8; 8]);
            seal_default::<BoardCipher>(&key, &nonce, level, &a, &mut by_board, &mut board_mic)
                .unwrap();
            prop_assert_eq!(&by_board, &by_crate);
            prop_assert_eq!(board_mic, crate_mic);
            let a_blocks = if a.is_empty() { 0 } else { (a.len() + 2).div_ceil(16) };
            let m_blocks = m.len().div_ceil(16);
            prop_assert_eq!(BLOCKS.get(), 1 + a_blocks + m_blocks + 1 + m_blocks);
            unseal_default::<SoftAes>(&key, &nonce, level, &a, &mut ours, &crate_mic).unwrap();
            prop_assert_eq!(&ours, &m);
            let mut bad = crate_mic;
            bad[flip / 8] ^= 1 << (flip % 8);
            let refused = unseal_default::<SoftAes>(&key, &nonce, level, &a, &mut by_crate, &bad);
            prop_assert_eq!(refused, Err(SecError::BadMic));
            prop_assert!(by_crate.iter().all(|b| *b == 0));
        }
    }
}

#[test]
fn the_mpdu_forms_are_the_psdu_forms_without_the_fcs() {
    // What a node sends: the same bytes as `secure_default` less the FCS (the MIC never
    // covers the FCS), and what it opens: the same frame, the FCS cut off at the edge.
    let (aux, ext) = (AuxRepr::new(1, 9), ext_addr(0xBEEF, 0x0001));
    let mut psdu = [0u8; MAX_PSDU];
    let n = secure_default(&header(), &aux, &ANNEX_KEY, ext, b"abcd", &mut psdu).unwrap();
    let mut mpdu = [0u8; MAX_PSDU];
    let m =
        secure_default_mpdu_with::<SoftAes>(&header(), &aux, &ANNEX_KEY, ext, b"abcd", &mut mpdu)
            .unwrap();
    assert_eq!(&mpdu[..m], &psdu[..n - 2]);
    let mut scratch = [0u8; mac::MAX_PAYLOAD];
    let opened =
        open_default_mpdu_with::<SoftAes, _>(&mpdu[..m], node_lookup(ANNEX_KEY), &mut scratch)
            .unwrap();
    assert_eq!((opened.aux, opened.payload), (aux, &b"abcd"[..]));
    // A bit flipped under the MIC: refused, FCS or not.
    mpdu[10] ^= 1;
    assert_eq!(
        open_default_mpdu_with::<SoftAes, _>(&mpdu[..m], node_lookup(ANNEX_KEY), &mut scratch),
        Err(SecError::BadMic)
    );
    // No room for the MIC in the MPDU buffer.
    let mut small = [0u8; 20];
    assert_eq!(
        secure_default_mpdu_with::<SoftAes>(&header(), &aux, &ANNEX_KEY, ext, b"abcd", &mut small),
        Err(SecError::NoRoom)
    );
}
