//! Reliable, ordered event delivery between a publisher and one subscriber, over a radio that
//! loses, duplicates and reorders frames. Pure state machines: time comes in as milliseconds,
//! messages go out through a closure, so the runtime, the simulator and the tests share them.
//!
//! Go-back-N with cumulative acknowledgements:
//! - the [`Sender`] numbers each event (`seq`, per `epoch`), keeps it until acknowledged,
//!   sends at most [`WINDOW`] unacknowledged events, and on a timeout resends them all with
//!   exponential backoff; after [`ALARM_AFTER`] timeouts without progress it raises a link
//!   alarm (and keeps trying);
//! - the [`Receiver`] delivers only the next expected `seq`, so every event is delivered
//!   exactly once and in publisher order; frames up to [`WINDOW`] ahead are held until the
//!   gap before them fills (the radio reorders); duplicates are dropped; every frame of the
//!   current epoch is answered with the cumulative acknowledgement.
//!
//! A gap is never skipped: if the sender's queue overflows the link is [`LinkState::Broken`]:
//! it still delivers the events it had queued, but takes no new one in this epoch, so a
//! subscriber can stall but never act out of turn. Only a new epoch (a new [`Sender`]: a new
//! table, or the operator's reset) re-establishes it.

use config_schema::wire::msg::Message;
use config_schema::Topic;
use heapless::Deque;

/// Unacknowledged events in flight.
pub const WINDOW: usize = 4;
/// Events queued per subscriber (in flight or waiting for the window).
pub const QUEUE: usize = 16;
/// First retransmission timeout: above the round trip of a frame and its acknowledgement
/// (two frames of airtime plus the medium's delay, at most 24 ms in the tests).
pub const RTO_MS: u64 = 30;
/// Largest retransmission timeout.
pub const RTO_MAX_MS: u64 = 120;
/// Timeouts without progress before the link alarm.
pub const ALARM_AFTER: u8 = 8;
/// A fresh receiver asks its publisher to number the link again this many ms after the
/// first event it dropped, then at most once per this many ms ([`Receiver::ask`]): above
/// the radio's reordering and the publisher's first timeout, so that a seq 0 behind the
/// frames it dropped has been sent again once before it asks.
pub const ASK_MS: u64 = 50;

/// Whether epoch (or seq) `a` comes before `b` (serial order on `u16`).
pub fn before(a: u16, b: u16) -> bool {
    (a.wrapping_sub(b) as i16) < 0
}

/// Health of a link, as status shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LinkState {
    /// Acknowledgements arrive.
    Ok,
    /// The peer stopped acknowledging; still retrying.
    Alarm,
    /// The queue overflowed: no new event is taken in this epoch (what was queued is still
    /// delivered).
    Broken,
}

/// Counters of one sender.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SenderCounters {
    /// Event frames sent for the first time.
    pub sent: u32,
    /// Event frames sent again.
    pub retried: u32,
    /// Events acknowledged.
    pub acked: u32,
}

/// The publisher's side of one link.
#[derive(Debug, Clone)]
pub struct Sender {
    epoch: u16,
    /// Seq of `pending[0]`.
    base: u16,
    pending: Deque<Topic, QUEUE>,
    deadline: Option<u64>,
    timeouts: u8,
    state: LinkState,
    counters: SenderCounters,
}

/// Why an event was not queued.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LinkBroken;

impl Sender {
    /// A link starting a new epoch (call with a new epoch after every boot or new table).
    pub fn new(epoch: u16) -> Self {
        Sender {
            epoch,
            base: 0,
            pending: Deque::new(),
            deadline: None,
            timeouts: 0,
            state: LinkState::Ok,
            counters: SenderCounters::default(),
        }
    }

    pub fn state(&self) -> LinkState {
        self.state
    }

    /// The epoch this link numbers its events in.
    pub fn epoch(&self) -> u16 {
        self.epoch
    }

    pub fn counters(&self) -> SenderCounters {
        self.counters
    }

    /// Events not yet acknowledged.
    pub fn unacked(&self) -> usize {
        self.pending.len()
    }

    /// When [`Sender::poll`] next has work.
    pub fn deadline(&self) -> Option<u64> {
        self.deadline
    }

    fn rto(&self) -> u64 {
        (RTO_MS << self.timeouts.min(8)).min(RTO_MAX_MS)
    }

    fn event(&self, index: usize) -> Option<Message<'static>> {
        let topic = *self.pending.iter().nth(index)?;
        Some(Message::Event {
            epoch: self.epoch,
            seq: self.base.wrapping_add(index as u16),
            topic,
        })
    }

    /// Queues an event; sends it now if the window allows. A full queue breaks the link:
    /// the event is refused, and so is every later one in this epoch.
    pub fn push(
        &mut self,
        topic: Topic,
        now: u64,
        mut send: impl FnMut(Message<'static>),
    ) -> Result<(), LinkBroken> {
        if self.state == LinkState::Broken {
            return Err(LinkBroken);
        }
        if self.pending.push_back(topic).is_err() {
            self.state = LinkState::Broken;
            return Err(LinkBroken);
        }
        let index = self.pending.len() - 1;
        if index < WINDOW {
            if let Some(msg) = self.event(index) {
                send(msg);
                crate::count(&mut self.counters.sent);
            }
        }
        if self.deadline.is_none() {
            self.deadline = Some(now + self.rto());
        }
        Ok(())
    }

    /// An acknowledgement arrived: drops what it covers, sends what the window now allows.
    pub fn on_ack(
        &mut self,
        epoch: u16,
        next: u16,
        now: u64,
        mut send: impl FnMut(Message<'static>),
    ) {
        if epoch != self.epoch {
            return;
        }
        let acked = usize::from(next.wrapping_sub(self.base));
        if acked == 0 || acked > self.pending.len() {
            return; // nothing new, or not about this window
        }
        let window_end = WINDOW.min(self.pending.len());
        for _ in 0..acked {
            self.pending.pop_front();
        }
        self.base = next;
        self.counters.acked += acked as u32;
        self.timeouts = 0;
        if self.state == LinkState::Alarm {
            self.state = LinkState::Ok;
        }
        // Events that were queued behind the window and now fit into it.
        let already_sent = window_end.saturating_sub(acked);
        for index in already_sent..WINDOW.min(self.pending.len()) {
            if let Some(msg) = self.event(index) {
                send(msg);
                crate::count(&mut self.counters.sent);
            }
        }
        self.deadline = (!self.pending.is_empty()).then(|| now + self.rto());
    }

    /// Whether none of this link's events was acknowledged in its epoch: its first
    /// unacknowledged event (or its next) is seq 0, which a fresh receiver takes as it is.
    pub fn starts_at_zero(&self) -> bool {
        self.base == 0
    }

    /// Whether this link numbers in an epoch older than `epoch` (serial order on `u16`).
    pub fn older_than(&self, epoch: u16) -> bool {
        before(self.epoch, epoch)
    }

    /// The subscriber lost its side of the link (it rebooted): the events it has not
    /// acknowledged are numbered again from 0 in `epoch` (newer than this link's) and sent
    /// at the next poll. That is no progress: an alarm stays until an acknowledgement. A
    /// broken link stays broken (only a reset re-establishes it).
    pub fn renumber(&mut self, epoch: u16, now: u64) {
        self.epoch = epoch;
        self.base = 0;
        self.resend(now);
    }

    /// Sends the window again at the next poll (the subscriber can take it now).
    pub fn resend(&mut self, now: u64) {
        self.deadline = (!self.pending.is_empty()).then_some(now);
    }

    /// Resends the window if its timeout passed.
    pub fn poll(&mut self, now: u64, mut send: impl FnMut(Message<'static>)) {
        let Some(deadline) = self.deadline else {
            return;
        };
        if now < deadline {
            return;
        }
        for index in 0..WINDOW.min(self.pending.len()) {
            if let Some(msg) = self.event(index) {
                send(msg);
                crate::count(&mut self.counters.retried);
            }
        }
        self.timeouts = self.timeouts.saturating_add(1);
        if self.timeouts >= ALARM_AFTER && self.state == LinkState::Ok {
            self.state = LinkState::Alarm;
        }
        self.deadline = Some(now + self.rto());
    }
}

/// What the receiver makes of an event frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Received {
    /// Deliver these topics to the engine, in this order (each exactly once, in publisher
    /// order: a frame that fills a gap releases the frames held behind it).
    pub deliver: heapless::Vec<Topic, { WINDOW + 1 }>,
    /// Send this acknowledgement back (`None`: say nothing).
    pub ack: Option<Message<'static>>,
}

/// Where a receiver stands (eight bytes: a receiver per peer, on every node).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
enum Cursor {
    /// Fresh (the node booted, or the peer is new to its table): no event taken yet.
    #[default]
    Fresh,
    /// Fresh, and it dropped an event (past seq 0) at `at` (ms, wrapping).
    Noted { at: u32 },
    /// Fresh, and it asked its publisher at `at` (ms, wrapping) to number the link again
    /// in `wanted` ([`Receiver::ask`]): it takes no older epoch.
    Asked { wanted: u16, at: u32 },
    /// Epoch `epoch` taken, `next` the next seq expected.
    At { epoch: u16, next: u16 },
}

/// Events that arrived early, `WINDOW` slots: slot i is seq `next + 1 + i`. Bit i of
/// `mask` says slot i holds `topics[i]` (a slot not holding one reads 0: equal holdings
/// compare equal); none held is one compare.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
struct Held {
    mask: u8,
    topics: [Topic; WINDOW],
}

impl Held {
    /// No slot holds an event.
    #[inline(always)]
    fn empty(&self) -> bool {
        self.mask == 0
    }

    /// Slot `i` holds an event.
    fn holds(&self, i: usize) -> bool {
        self.mask & (1 << i) != 0
    }

    /// Slot `i` (below `WINDOW`) holds `topic` from now on.
    fn put(&mut self, i: usize, topic: Topic) {
        if let Some(t) = self.topics.get_mut(i) {
            *t = topic;
            self.mask |= 1 << i;
        }
    }

    /// The slots re-indexed from a `next` one higher: slot 0's event, if any, is taken
    /// out (returned), the others move down one.
    fn shift(&mut self) -> Option<Topic> {
        let [first, rest @ ..] = self.topics;
        let first = (self.mask & 1 != 0).then_some(first);
        self.topics = [0; WINDOW];
        self.topics[..WINDOW - 1].copy_from_slice(&rest);
        self.mask >>= 1;
        first
    }
}

/// The subscriber's side of one link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Receiver {
    /// Where the link stands.
    cursor: Cursor,
    /// Events that arrived early.
    held: Held,
    /// Duplicates, stale and out-of-window frames dropped.
    pub dropped: u32,
}

impl Receiver {
    pub fn new() -> Self {
        Self::default()
    }

    /// An event frame arrived.
    pub fn on_event(&mut self, epoch: u16, seq: u16, topic: Topic) -> Received {
        let mut deliver = heapless::Vec::new();
        let ack = self.receive(epoch, seq, topic, &mut deliver);
        Received {
            deliver,
            ack: ack.map(|next| Message::EventAck { epoch, next }),
        }
    }

    /// [`Receiver::on_event`] without building the [`Received`]: the topics to deliver are
    /// pushed onto `deliver` (empty), and `Some(next)` says to acknowledge with
    /// `EventAck { epoch, next }` (`None`: say nothing).
    #[inline]
    pub fn receive(
        &mut self,
        epoch: u16,
        seq: u16,
        topic: Topic,
        deliver: &mut heapless::Vec<Topic, { WINDOW + 1 }>,
    ) -> Option<u16> {
        let next = match self.cursor {
            Cursor::At {
                epoch: current,
                next,
            } if current == epoch => next,
            // An older epoch: a frame from before the publisher restarted.
            Cursor::At { epoch: current, .. } if before(epoch, current) => {
                return self.drop_frame()
            }
            // A newer epoch (or the first one seen) is anchored at seq 0 only.
            _ if seq != 0 => return self.drop_frame(),
            // Fresh, and it asked for a renumbering: not an epoch older than it asked for
            // (whose events the publisher may be numbering again in a newer one).
            Cursor::Asked { wanted, .. } if before(epoch, wanted) => return self.drop_frame(),
            _ => {
                self.held = Held::default();
                0
            }
        };
        let ahead = usize::from(seq.wrapping_sub(next));
        let mut next = next;
        if ahead == 0 {
            let _ = deliver.push(topic);
            next = next.wrapping_add(1);
            // Re-index the held frames from the new `next`, releasing those now in order
            // (none held: nothing to re-index).
            while !self.held.empty() {
                match self.held.shift() {
                    Some(t) => {
                        let _ = deliver.push(t);
                        next = next.wrapping_add(1);
                    }
                    None => break,
                }
            }
        } else if (1..=WINDOW).contains(&ahead) && !self.held.holds(ahead - 1) {
            self.held.put(ahead - 1, topic);
        } else {
            self.dropped += 1; // a duplicate, or beyond the sender's window
        }
        self.cursor = Cursor::At { epoch, next };
        Some(next)
    }

    /// This receiver dropped an event of `epoch` at `now`: the epoch it asks the publisher
    /// to number the link again in, from seq 0 with the events not acknowledged (sent as
    /// a `Challenge` in clear on a robot without link keys), if it is to ask. Only a fresh
    /// receiver asks (it has taken no epoch since the node booted: it lost its side of the
    /// link while the publisher numbered on), and only [`ASK_MS`] after the first event it
    /// dropped (a link that just started gets its seq 0 a moment after the seq 1 the radio
    /// reordered ahead of it), then at most once per `ASK_MS`. From then on it takes no
    /// epoch older than the one it asked for, and each time it asks again (the publisher
    /// did not hear, or that epoch's seq 0 was lost) it asks for one newer than every
    /// epoch it dropped: an event the publisher numbered again in an epoch it asked for
    /// before is never taken, so nothing is delivered twice.
    pub fn ask(&mut self, epoch: u16, now: u64) -> Option<u16> {
        // Milliseconds in 32 bits, compared wrapping: an interval is far below 49 days.
        let now = now as u32;
        let since = |at: u32| now.wrapping_sub(at) < ASK_MS as u32;
        let wanted = match self.cursor {
            Cursor::At { .. } => return None,
            Cursor::Fresh => {
                self.cursor = Cursor::Noted { at: now };
                return None;
            }
            Cursor::Noted { at } | Cursor::Asked { at, .. } if since(at) => return None,
            Cursor::Asked { wanted, .. } if before(epoch, wanted) => wanted,
            Cursor::Noted { .. } | Cursor::Asked { .. } => epoch.wrapping_add(1),
        };
        self.cursor = Cursor::Asked { wanted, at: now };
        Some(wanted)
    }

    /// [`Receiver::receive`] of the event this receiver expects next (`seq` the next of
    /// the epoch it is at) while it holds none: the one event to deliver is this one, and
    /// `Some(next)`, to acknowledge with, is what `receive` returns. `None`: any other
    /// frame, nothing changed ([`Receiver::receive`] takes it).
    #[inline(always)]
    pub fn next_in_order(&mut self, epoch: u16, seq: u16) -> Option<u16> {
        match &mut self.cursor {
            Cursor::At {
                epoch: current,
                next,
            } if *current == epoch && *next == seq && self.held.empty() => {
                *next = seq.wrapping_add(1);
                Some(*next)
            }
            _ => None,
        }
    }

    fn drop_frame(&mut self) -> Option<u16> {
        self.dropped += 1;
        None
    }
}
