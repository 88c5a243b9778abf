//! Every reader of bytes from outside in `config-schema`'s wire formats, whatever the
//! bytes: a MAC frame, a management message (as the tool and as a node read it), a link
//! message, a medium link message and the medium's stream deframer, a security-opened
//! frame (under a fixed key), a key block and a deployment slot. Never a panic; a management
//! message and a link message that parse emit back to bytes that parse the same, and the
//! link's own fast reader reads what the message codec reads (every canonical encoding).
#![no_main]

use config_schema::link_keys::{decode_deployment, LinkKeys};
use config_schema::wire::medium::{Deframer, Link};
use config_schema::wire::msg::{LinkMessage, Message};
use config_schema::wire::{mac, security};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = mac::Frame::parse(data);
    let _ = mac::Frame::parse_mpdu(data);
    // The link's own reader (a node's fast path) reads what the message codec reads, and
    // reads every canonical encoding (a longer one is left to the codec).
    let general = Message::parse(data).ok().and_then(|m| LinkMessage::of(&m));
    let fast = LinkMessage::parse(data);
    if fast.is_some() {
        assert_eq!(fast, general, "LinkMessage::parse == Message::parse");
    }
    if let Some(m) = general {
        let mut canonical = [0u8; LinkMessage::MAX_LEN];
        let n = m.write(&mut canonical);
        if canonical.get(..n) == Some(data) {
            assert_eq!(
                fast, general,
                "a canonical link message is read by the fast path"
            );
        }
    }
    if let Ok(m) = Message::parse(data) {
        let mut buf = [0u8; 256];
        if let Ok(n) = m.emit(&mut buf) {
            assert_eq!(
                Message::parse(&buf[..n]).ok(),
                Some(m),
                "parse(emit(m)) == m"
            );
        }
    }
    let _ = Message::parse_node(data);
    if let Some(m) = LinkMessage::parse(data) {
        let mut buf = [0u8; LinkMessage::MAX_LEN];
        let n = m.write(&mut buf);
        assert_eq!(
            LinkMessage::parse(&buf[..n]),
            Some(m),
            "parse(emit(m)) == m"
        );
    }
    let _ = Link::parse(data);
    let mut deframer = Deframer::<512>::new();
    for chunk in data.chunks(37) {
        let _ = deframer.push(chunk);
        while let Ok(Some(body)) = deframer.take() {
            let _ = Link::parse(body);
        }
    }
    let mut scratch = [0u8; 128];
    let _ = security::open(data, |_, _| Some(([7; 16], [1; 8])), &mut scratch);
    let _ = LinkKeys::decode(data);
    let _ = decode_deployment(data);
});
