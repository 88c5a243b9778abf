//! The simulator's lossy radio: every link (publisher -> subscriber) runs the node's own
//! reliable link ([`crate::link`]: window, queue, retransmission with backoff, alarm,
//! broken on overflow), and the radio loses each frame (event or acknowledgement) with a
//! fixed probability, from a seeded generator, so a run is reproducible.

use config_schema::wire::msg::Message;
use config_schema::Topic;

use crate::link::{LinkState, Receiver, Sender};

/// A frame on the air of one link.
#[derive(Debug, Clone, Copy)]
pub(super) enum Frame {
    /// Publisher -> subscriber.
    Event { epoch: u16, seq: u16, topic: Topic },
    /// Subscriber -> publisher.
    Ack { epoch: u16, next: u16 },
}

impl Frame {
    /// The frame of a link message (`None` for any other message).
    pub(super) fn of(msg: &Message<'_>) -> Option<Frame> {
        match *msg {
            Message::Event { epoch, seq, topic } => Some(Frame::Event { epoch, seq, topic }),
            Message::EventAck { epoch, next } => Some(Frame::Ack { epoch, next }),
            _ => None,
        }
    }
}

/// Both ends of one link and what the world has scheduled and traced for it.
pub(super) struct Link {
    pub tx: Sender,
    pub rx: Receiver,
    /// The sender deadline the scheduled poll is for, and its generation (a poll with an
    /// older generation is stale).
    pub poll_at: Option<u64>,
    pub poll_gen: u64,
    /// Whether the alarm / the break has been traced (once per episode).
    pub alarm_traced: bool,
    pub broken_traced: bool,
}

/// The lossy radio of a world of `n` nodes.
pub(super) struct Lossy {
    /// Loss threshold against the generator's upper 32 bits.
    threshold: u64,
    rng: u64,
    n: usize,
    links: Vec<Link>,
    pub sent: u64,
    pub lost: u64,
}

impl Lossy {
    pub(super) fn new(n: usize, loss: f64, seed: u64) -> Lossy {
        let loss = if loss.is_nan() {
            0.0
        } else {
            loss.clamp(0.0, 1.0)
        };
        Lossy {
            threshold: (loss * f64::from(u32::MAX)) as u64,
            rng: seed,
            n,
            links: (0..n * n)
                .map(|_| Link {
                    tx: Sender::new(0),
                    rx: Receiver::new(),
                    poll_at: None,
                    poll_gen: 0,
                    alarm_traced: false,
                    broken_traced: false,
                })
                .collect(),
            sent: 0,
            lost: 0,
        }
    }

    /// The link from `from` to `to` (both node indices of the world).
    pub(super) fn link(&mut self, from: usize, to: usize) -> Option<&mut Link> {
        self.links.get_mut(from * self.n + to)
    }

    pub(super) fn poll_gen(&self, from: usize, to: usize) -> Option<u64> {
        self.links.get(from * self.n + to).map(|l| l.poll_gen)
    }

    /// Whether the next frame is lost (splitmix64).
    pub(super) fn lose(&mut self) -> bool {
        self.rng = self.rng.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        self.sent += 1;
        let lost = (z >> 32) < self.threshold;
        if lost {
            self.lost += 1;
        }
        lost
    }
}

/// Whether a link state is an alarm.
pub(super) fn alarmed(state: LinkState) -> bool {
    state == LinkState::Alarm
}
