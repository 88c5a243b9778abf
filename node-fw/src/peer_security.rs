//! Frame security between peers: the link keys a node's table came with, which key opens a
//! peer's frame, the replay floor of every peer, and the freshness handshake after a boot.
//!
//! A node whose running table came with a key block ([`LinkKeys`]) secures every frame it
//! sends on the robot's PAN (events, acknowledgements, challenges) at ENC-MIC-64 under its
//! send key for that peer, key index [`link_key_index`] of the table's generation, and
//! takes there only frames secured so by a peer under that peer's key. Without a key block
//! (an explicitly unsecured robot, or a node never pushed keys) frames stay unsecured.
//!
//! **Overlap.** When a new generation runs, the previous generation's receive keys are
//! kept: a peer that has not switched yet still reaches this node, until that peer is
//! heard under the new key (it switched: its old-key frames are replays or forgeries from
//! then on) or [`OVERLAP_MS`] after the first peer's frame that opened after the switch,
//! whichever comes first. A node only sends
//! under its running generation's keys; a peer still on the old generation cannot open
//! them and the link layer resends until it switches. So a switch-over loses no event.
//!
//! **Replay.** Every sender's frame counter is one per device and strictly increasing
//! across all its keys, so the floor is per peer, kept across generations. After a boot
//! the node knows no floor: an authentic frame from a peer without one is not acted on;
//! the node sends that peer `Challenge { nonce }` (the challenge frame's own counter, or
//! the nonce of its challenge to the peer sent within [`REPEAT_MS`] and not answered yet)
//! and takes the counter of the peer's `ChallengeAnswer` with that nonce as the floor, or
//! the highest counter of the peer's authentic frames that came before it, if higher (an
//! answer the peer sent before it booted again, come late, would set a floor under
//! frames of its new life: its old acknowledgements would then pass). So
//! that the first events of a new table (or after a boot) do not wait for it, the node
//! challenges every peer it knows no floor of as soon as it runs with keys. A peer
//! answers a challenge even if it has no floor for the challenger itself (answering takes
//! nothing in; with a floor, a replayed challenge is refused like any replay), at most
//! once per [`ANSWER_MS`] per peer; it challenges a peer at most once per
//! [`CHALLENGE_MS`], and an answer to either of its last two challenges sets the floor (on
//! a busy medium an answer can arrive after the next challenge went out) if it comes
//! within [`ANSWER_WITHIN_MS`] of it.

use config_schema::limits::MAX_PEERS;
use config_schema::link_keys::LinkKeys;
use config_schema::wire::mac::Header;
use config_schema::wire::msg::{Message, SecurityCounters};
use config_schema::wire::security::{
    self, ext_addr, link_key_index,
    replay::{ReplayError, ReplayGuard},
    AuxRepr, Opened, SecError, KEY_LEN,
};
use heapless::vec::VecView;
use heapless::Vec;

use crate::cipher::NodeCipher;

/// How long after a switch the previous generation's keys still open a peer's frames.
pub const OVERLAP_MS: u64 = 10_000;
/// At most one answer per peer per this many ms (each spends a frame counter: a flood of
/// replays must not use it up).
pub const ANSWER_MS: u64 = 50;
/// At most one challenge per peer per this many ms: twice [`ANSWER_MS`], so a live peer
/// answers every challenge (with equal intervals, jitter held some answers back).
pub const CHALLENGE_MS: u64 = 2 * ANSWER_MS;

/// Challenges a node sends a peer it knows no floor of once it runs with keys, one per
/// this many ms (until answered).
pub const GREET_TRIES: u8 = 5;
pub const GREET_EVERY_MS: u64 = 100;

/// The replay guard's key index for every link key: a peer's counter is one per device,
/// so its floor holds whatever key it used.
const ANY_LINK_KEY: u8 = 1;

/// What became of a frame from a peer.
#[derive(Debug)]
pub enum Verdict<'s> {
    /// Authentic and fresh: act on it.
    Accept(&'s [u8]),
    /// Authentic, but this node knows no floor for the peer yet: challenge it (if
    /// `challenge` is set; else the last challenge is too recent). Not acted on.
    Challenge { peer: u16, challenge: bool },
    /// Authentic: the peer asks this node to prove freshness; answer it with `nonce` (if
    /// `answer`: at most once per [`ANSWER_MS`]).
    Answer {
        peer: u16,
        nonce: u32,
        answer: bool,
        /// This node knows no floor of the peer either: challenge it back (the peer that
        /// greets last after a push is then known both ways before any event).
        challenge: bool,
        /// The peer may have lost its side of our link (it booted): number the link again
        /// if the peer took some of its epoch already (`NodeCore` decides: a link none of
        /// whose events was acknowledged in its epoch starts at seq 0, which a fresh
        /// receiver takes as it is). Not for a reset's greeting, which kept its receivers.
        renumber: bool,
    },
    /// The answer to this node's challenge: the peer's floor is set. Nothing else to do.
    Answered,
    /// Refused; counted by its reason.
    Dropped,
}

/// A node's peer security state.
#[derive(Debug, Default)]
pub struct PeerSecurity {
    current: Option<LinkKeys>,
    previous: Option<LinkKeys>,
    /// Peers heard under the current keys (their previous-generation frames are refused).
    switched: Vec<u16, MAX_PEERS>,
    /// Until when the previous keys open anything (from the first frame after the switch).
    overlap_until: Option<u64>,
    replay: ReplayGuard<MAX_PEERS>,
    /// Challenges sent and not answered.
    challenges: Pending<MAX_PEERS>,
    /// Peers to challenge before any event (set when keys are installed), with the tries
    /// left and when the next is due: the first events of a new table or a boot then find
    /// their floors established. Retried because a peer that has not switched to this
    /// generation yet cannot open the challenge.
    greet: Vec<(u16, u8, u64), MAX_PEERS>,
    /// Per peer: when it may be challenged, and answered, again.
    next_challenge: Vec<(u16, u64), MAX_PEERS>,
    next_answer: Vec<(u16, u64), MAX_PEERS>,
    /// Per peer: the nonce this node repeats in its challenges to it while it is not
    /// answered, and when it first sent it ([`PeerSecurity::challenge`]; forgotten when a new
    /// table runs).
    repeating: Vec<(u16, u32, u64), MAX_PEERS>,
    /// Per peer of unknown floor: the highest counter of its authentic frames come so far.
    /// The floor an answer sets is at least that: an answer (or any frame) the peer sent
    /// before it booted again, come late, must not set a floor below what its new life
    /// sent already (its old acknowledgements would pass, and move a link the new life
    /// knows nothing of).
    seen: Vec<(u16, u32), MAX_PEERS>,
}

/// How long a node repeats a challenge's nonce to a peer that has not answered: a boot's
/// greetings and their retries ([`crate::restart::GREETED_WITHIN_MS`]), no longer (an
/// answer to an older nonce, captured, would set the floor as long as it is repeated).
pub const REPEAT_MS: u64 = crate::restart::GREETED_WITHIN_MS;

/// An answer sets the floor only if it comes soon after the challenge (its last copy, for
/// a repeated nonce): far later than a peer answers on a busy medium, and soon, so that
/// an answer captured and held back from the node cannot set an old floor later (the
/// frames above it, refused while there was no floor, would then be taken as fresh).
/// Timed in ticks of [`ANSWER_TICK_MS`] (a `u32` a sender): an answer within
/// `ANSWER_WITHIN_MS` always counts, one [`ANSWER_TICK_MS`] later or more never does.
pub const ANSWER_WITHIN_MS: u64 = ANSWER_TICKS as u64 * ANSWER_TICK_MS;
/// The tick of [`ANSWER_WITHIN_MS`].
pub const ANSWER_TICK_MS: u64 = 1 << TICK_SHIFT;
const TICK_SHIFT: u32 = 10;
const ANSWER_TICKS: u32 = 2;

/// `now` in ticks of [`ANSWER_TICK_MS`] (a `u32` wraps after 139 years).
fn tick(now: u64) -> u32 {
    (now >> TICK_SHIFT) as u32
}

/// Whether an answer at tick `now` comes in time for a challenge sent at tick `sent`.
fn in_time(now: u32, sent: u32) -> bool {
    now.wrapping_sub(sent) <= ANSWER_TICKS
}

/// Whether `peer` may be sent another handshake frame at `now`, at most one per
/// `every` ms (if so, the next may go at `now + every`).
fn may(times: &mut Vec<(u16, u64), MAX_PEERS>, peer: u16, now: u64, every: u64) -> bool {
    if let Some((_, next)) = times.iter_mut().find(|(p, _)| *p == peer) {
        if now < *next {
            return false;
        }
        *next = now + every;
        return true;
    }
    // A new one: in a free entry, else in the one free again the longest (only authentic
    // frames' senders come here, at most the table's peers: a full list is no flood).
    if let Err(entry) = times.push((peer, now + every)) {
        if let Some(oldest) = times.iter_mut().min_by_key(|(_, next)| *next) {
            *oldest = entry;
        }
    }
    true
}

impl PeerSecurity {
    /// Whether the running table came with link keys (its events are secured).
    pub fn secured(&self) -> bool {
        crate::FRAME_SECURITY && self.current.is_some()
    }

    /// The running table's keys.
    pub fn current(&self) -> Option<&LinkKeys> {
        self.current.as_ref()
    }

    /// A new table runs, with `keys` (or none) for its `peers`. The previous
    /// generation's keys stay for the overlap (unless they share its key index); floors of
    /// nodes that are no longer peers are forgotten (a peer again later is challenged).
    pub fn install(&mut self, keys: Option<LinkKeys>, peers: &[u16]) {
        let old = self.current.take();
        self.previous = match (&old, &keys) {
            (Some(o), Some(n)) if link_key_index(o.generation) == link_key_index(n.generation) => {
                None
            }
            _ => old,
        };
        self.current = keys;
        // The cipher's kept schedules of the keys dropped go too.
        crate::cipher::forget_keys();
        self.switched.clear();
        self.overlap_until = None;
        let mut floors = ReplayGuard::new();
        for e in self.replay.iter().filter(|e| peers.contains(&e.sender)) {
            // As many entries as before, at most: there is room.
            let _ = floors.check_and_accept(e.sender, e.key_index, e.last);
        }
        self.replay = floors;
        self.challenges.retain(peers);
        // (`remove_at`: `retain` shifts the entries with a 1.5 KB `memmove`.)
        let mut i = 0;
        while let Some((p, _)) = self.seen.get(i) {
            if peers.contains(p) {
                i += 1;
            } else {
                crate::remove_at(&mut self.seen, i);
            }
        }
        self.repeating.clear();
        self.greet.clear();
        if self.current.is_some() {
            for &p in peers {
                if self.replay.last(p, ANY_LINK_KEY).is_none() {
                    let _ = self.greet.push((p, GREET_TRIES, 0));
                }
            }
        }
    }

    /// The next peer to challenge before any of its frames came (see `greet`), at `now`.
    pub fn next_greeting(&mut self, now: u64) -> Option<u16> {
        if !crate::FRAME_SECURITY {
            return None;
        }
        let replay = &self.replay;
        self.greet
            .retain(|(p, tries, _)| *tries > 0 && replay.last(*p, ANY_LINK_KEY).is_none());
        let (peer, tries, next) = self.greet.iter_mut().find(|(_, _, at)| *at <= now)?;
        *tries -= 1;
        *next = now + GREET_EVERY_MS;
        let peer = *peer;
        may(&mut self.next_challenge, peer, now, CHALLENGE_MS).then_some(peer)
    }

    /// When the next greeting is due, if any is.
    pub fn greeting(&self) -> Option<u64> {
        if !crate::FRAME_SECURITY {
            return None;
        }
        self.greet.iter().map(|(_, _, at)| *at).min()
    }

    /// The send key to `dst` of the running generation and its key index, if `dst` is a
    /// peer of it: the node secures its frames to `dst` with it (in the one secured
    /// branch it shares with its management frames).
    pub fn send_key(&self, dst: u16) -> Option<([u8; KEY_LEN], u8)> {
        let keys = self.current.as_ref()?;
        Some((keys.of(dst)?.send, link_key_index(keys.generation)))
    }

    /// The receive key for a frame from `src` under `key_index`, at `now`.
    fn key_for(&self, src: u16, key_index: u8, now: u64) -> Option<[u8; KEY_LEN]> {
        if let Some(k) = self
            .current
            .as_ref()
            .filter(|k| link_key_index(k.generation) == key_index)
        {
            return k.of(src).map(|p| p.receive);
        }
        // Not begun (no peer's frame opened since the switch) is open.
        let overlap = self.overlap_until.is_none_or(|t| now < t) && !self.switched.contains(&src);
        self.previous
            .as_ref()
            .filter(|k| overlap && link_key_index(k.generation) == key_index)
            .and_then(|k| k.of(src))
            .map(|p| p.receive)
    }

    /// Opens a secured frame from a peer (`me`: this node's address, never a sender),
    /// checks its counter, and runs the handshake. Every refusal is counted.
    /// A frame under the key index of `staged` (the generation this node has staged) is a
    /// peer that switched a moment earlier: dropped, not counted as a security refusal.
    /// (The node does the same in its parts, sharing the open and the message parse with
    /// its management path: [`PeerSecurity::lookup`],
    /// [`PeerSecurity::refused`], [`PeerSecurity::admit`].)
    pub fn open<'s>(
        &mut self,
        psdu: &[u8],
        me: u16,
        staged: u32,
        now: u64,
        scratch: &'s mut [u8],
        counters: &mut SecurityCounters,
    ) -> Verdict<'s> {
        if !crate::FRAME_SECURITY {
            return Verdict::Dropped;
        }
        // The FCS is the radio edge's: checked here for a PSDU off the medium.
        let (mpdu, opened) = match config_schema::wire::mac::strip_fcs(psdu) {
            Ok(mpdu) => (
                mpdu,
                security::open_default_mpdu_with::<NodeCipher, _>(
                    mpdu,
                    |header, aux| self.lookup(header, aux, me, now),
                    scratch,
                ),
            ),
            Err(e) => (psdu, Err(SecError::from(e))),
        };
        match opened {
            Ok(opened) => {
                let message = Message::parse(opened.payload);
                self.admit(&opened, &message, now, counters)
            }
            Err(e) => {
                self.refused(key_index_of(mpdu), staged, e, counters);
                Verdict::Dropped
            }
        }
    }

    /// A secured frame from a peer opened at `now`: the overlap of the previous
    /// generation's keys runs from the first one after a switch (not from a frame that
    /// did not open: anyone in range can send one, and would end the overlap early).
    fn note_frame(&mut self, now: u64) {
        self.overlap_until.get_or_insert(now + OVERLAP_MS);
    }

    /// The receive key and the sender's extended address that open a frame with `header`
    /// and `aux` at `now` (`me`: this node, never a sender), if any.
    pub fn lookup(
        &self,
        header: &Header,
        aux: &AuxRepr,
        me: u16,
        now: u64,
    ) -> Option<([u8; KEY_LEN], [u8; 8])> {
        let index = aux.key_id.index()?;
        self.receive_key(header.src, index, me, now)
            .map(|k| (k, ext_addr(header.pan_id, header.src)))
    }

    /// The receive key that opens a frame from `src` under key index `key_index` at
    /// `now` (`me`: this node, never a sender), if any.
    pub fn receive_key(&self, src: u16, key_index: u8, me: u16, now: u64) -> Option<[u8; KEY_LEN]> {
        if src == me {
            return None;
        }
        self.key_for(src, key_index, now)
    }

    /// A peer's frame under key index `key_index` (if its auxiliary header says one) did
    /// not open (`e`): counted by its reason, unless it is under the key index of `staged`
    /// (a peer that switched a moment earlier).
    pub fn refused(
        &self,
        key_index: Option<u8>,
        staged: u32,
        e: SecError,
        counters: &mut SecurityCounters,
    ) {
        let ahead = staged != 0 && key_index == Some(link_key_index(staged));
        if !(e == SecError::UnknownKey && ahead) {
            count_refusal(e, counters);
        }
    }

    /// The replay check and the handshake of a peer's frame that opened, whose payload
    /// parsed to `message` (the first since a switch starts the overlap).
    pub fn admit<'s, E>(
        &mut self,
        opened: &Opened<'s>,
        message: &Result<Message<'_>, E>,
        now: u64,
        counters: &mut SecurityCounters,
    ) -> Verdict<'s> {
        self.note_frame(now);
        let Opened {
            header,
            aux,
            payload,
        } = opened;
        let src = header.src;
        let current = self
            .current
            .as_ref()
            .is_some_and(|k| aux.key_id.index() == Some(link_key_index(k.generation)));
        let floor = self.replay.last(src, ANY_LINK_KEY);
        let seen = match floor {
            Some(_) => 0,
            None => self.seen_from(src, aux.frame_counter),
        };
        if let (None, Ok(Message::Challenge { nonce })) = (floor, message) {
            // Answering takes nothing in: no floor needed (the peer rebooted, or both did).
            let answer = may(&mut self.next_answer, src, now, ANSWER_MS);
            // (A challenge of ours still unanswered may have gone to the peer before it had
            // this generation's keys: challenged again, at the handshake's rate.)
            let challenge = may(&mut self.next_challenge, src, now, CHALLENGE_MS);
            return Verdict::Answer {
                peer: src,
                nonce: *nonce,
                answer,
                challenge,
                renumber: *nonce != crate::restart::RESET_GREETING,
            };
        }
        if floor.is_none() {
            if self.challenges.answered(src, message, now) {
                if let Some(i) = self.seen.iter().position(|(p, _)| *p == src) {
                    crate::remove_at(&mut self.seen, i);
                }
                accept(&mut self.replay, src, ANY_LINK_KEY, seen, counters);
                return Verdict::Answered;
            }
            crate::count(&mut counters.challenged);
            let challenge = may(&mut self.next_challenge, src, now, CHALLENGE_MS);
            return Verdict::Challenge {
                peer: src,
                challenge,
            };
        }
        if !accept(
            &mut self.replay,
            src,
            ANY_LINK_KEY,
            aux.frame_counter,
            counters,
        ) {
            return Verdict::Dropped;
        }
        if current && !self.switched.contains(&src) {
            let _ = self.switched.push(src);
        }
        match message {
            Ok(Message::Challenge { nonce }) => Verdict::Answer {
                peer: src,
                nonce: *nonce,
                answer: may(&mut self.next_answer, src, now, ANSWER_MS),
                challenge: false,
                renumber: *nonce != crate::restart::RESET_GREETING,
            },
            _ => Verdict::Accept(payload),
        }
    }

    /// An authentic frame with `counter` came from `peer`, whose floor is unknown: the
    /// highest counter of its frames so far, this one's included. Kept for the current
    /// keys' peers only, at most [`MAX_PEERS`], so none is ever pushed out (a node that
    /// is no longer a peer, heard under the previous keys, delivers nothing here).
    fn seen_from(&mut self, peer: u16, counter: u32) -> u32 {
        if let Some((_, highest)) = self.seen.iter_mut().find(|(p, _)| *p == peer) {
            *highest = (*highest).max(counter);
            return *highest;
        }
        let ours = (self.current.as_ref()).is_some_and(|k| k.peers.iter().any(|p| p.peer == peer));
        if ours {
            let _ = self.seen.push((peer, counter));
        }
        counter
    }

    /// This node challenges `peer` in a frame with counter `counter`, with `flags`
    /// ([`crate::restart::GREETING`] or none), at `now`: the challenge's nonce, remembered
    /// until answered. The counter, unless the peer has not answered one sent within
    /// [`REPEAT_MS`] (its floor unknown): then that one's (with `flags` added), so that an
    /// answer to any of them (a greeting's retries, a challenge of a frame that came
    /// before the answer) sets the floor; with a nonce per copy only the last two count,
    /// and on a radio that reorders the answers to older ones came to nothing. Everything
    /// the peer sent before the first of them is still below the floor its answer sets.
    pub fn challenge(&mut self, peer: u16, counter: u32, flags: u32, now: u64) -> u32 {
        let nonce = self.repeated_nonce(peer, counter | flags, now);
        self.challenges.sent(peer, nonce, now);
        nonce
    }

    /// [`PeerSecurity::challenge`]'s nonce: `fresh`, or the one repeated to `peer`.
    fn repeated_nonce(&mut self, peer: u16, fresh: u32, now: u64) -> u32 {
        let unanswered = self.replay.last(peer, ANY_LINK_KEY).is_none();
        let at = self.repeating.iter().position(|r| r.0 == peer);
        if let Some(r) = at.and_then(|i| self.repeating.get_mut(i)) {
            if unanswered && now.saturating_sub(r.2) < REPEAT_MS {
                r.1 |= fresh & crate::restart::GREETING;
                return r.1;
            }
            *r = (peer, fresh, now);
        } else {
            if self.repeating.is_full() {
                crate::remove_at(&mut self.repeating, 0);
            }
            let _ = self.repeating.push((peer, fresh, now));
        }
        fresh
    }
}

/// Challenges a node sent and that were not answered yet: per sender the nonces of its
/// last [`OUTSTANDING`] challenges, newest first, and the tick the newest was last sent
/// in (an answer sets the floor within [`ANSWER_WITHIN_MS`] of it only, and the older
/// nonce is kept only if the newer went out within that time of it: none is answered more
/// than twice that after it was sent); the sender challenged longest ago forgotten when
/// full (shared by the management path and the peers').
#[derive(Debug, Default)]
pub struct Pending<const N: usize> {
    sent: Vec<Challenged, N>,
}

/// Challenges per sender whose answer still sets the floor.
pub const OUTSTANDING: usize = 2;
const _: () = assert!(OUTSTANDING == 2, "`sent` keeps the newest two");

/// A sender, the nonces of its pending challenges and the tick the newest was last sent in.
type Challenged = (u16, [Option<u32>; OUTSTANDING], u32);

impl<const N: usize> Pending<N> {
    /// `sender` was challenged with `nonce` at `now` (of its earlier challenges, the
    /// last [`OUTSTANDING`] - 1 still count, if the newest went out in time; a nonce sent
    /// again is as fresh as its last copy, and takes the older one's place too).
    pub fn sent(&mut self, sender: u16, nonce: u32, now: u64) {
        sent(self.sent.as_mut_view(), sender, nonce, now)
    }

    /// Whether `message` from `sender`, come at `now`, answers one of its pending
    /// challenges in time; if so none of its challenges is pending any more.
    pub fn answered<E>(&mut self, sender: u16, message: &Result<Message<'_>, E>, now: u64) -> bool {
        let Ok(Message::ChallengeAnswer { nonce }) = message else {
            return false;
        };
        answered(self.sent.as_mut_view(), sender, *nonce, now)
    }

    /// Forgets the challenges of senders not in `keep`.
    pub fn retain(&mut self, keep: &[u16]) {
        self.sent.retain(|(s, _, _)| keep.contains(s));
    }
}

// `Pending`'s work on its entries' `VecView`: one copy for the management (4) and the
// peer tables.
fn sent(sent: &mut VecView<Challenged>, sender: u16, nonce: u32, now: u64) {
    match sent.iter_mut().find(|(s, _, _)| *s == sender) {
        Some((_, nonces, at)) => {
            let [newest, _] = *nonces;
            let fresh = in_time(tick(now), *at);
            *nonces = [Some(nonce), newest.filter(|_| fresh)];
            *at = tick(now);
        }
        None => {
            if sent.is_full() {
                crate::to_end(sent, 0);
                sent.pop();
            }
            let _ = sent.push((sender, [Some(nonce), None], tick(now)));
        }
    }
}

fn answered(sent: &mut VecView<Challenged>, sender: u16, nonce: u32, now: u64) -> bool {
    let Some(i) = sent
        .iter()
        .position(|(s, n, at)| *s == sender && n.contains(&Some(nonce)) && in_time(tick(now), *at))
    else {
        return false;
    };
    crate::to_end(sent, i);
    sent.pop();
    true
}

/// Takes `counter` from `sender` under `key_index` if it is above the sender's floor (and
/// makes it the floor); else counts why not.
pub fn accept<const N: usize>(
    replay: &mut ReplayGuard<N>,
    sender: u16,
    key_index: u8,
    counter: u32,
    c: &mut SecurityCounters,
) -> bool {
    match replay.check_and_accept(sender, key_index, counter) {
        Ok(()) => true,
        Err(ReplayError::Replayed { .. }) => {
            crate::count(&mut c.replayed);
            false
        }
        Err(ReplayError::Full) => {
            crate::count(&mut c.table_full);
            false
        }
    }
}

/// The key index of secured frame `mpdu`'s auxiliary header, if it has one.
fn key_index_of(mpdu: &[u8]) -> Option<u8> {
    match config_schema::wire::mac::Frame::parse_mpdu(mpdu) {
        Ok(config_schema::wire::mac::Frame::Data { payload, .. }) => aux_key_index(payload),
        _ => None,
    }
}

/// The key index of the auxiliary header at the start of a secured frame's MAC
/// `payload`, if it has one.
pub fn aux_key_index(payload: &[u8]) -> Option<u8> {
    security::AuxHeader::new_checked(payload)
        .ok()
        .and_then(|aux| aux.key_index())
}

/// Counts why a secured frame did not open.
pub fn count_refusal(e: SecError, c: &mut SecurityCounters) {
    match e {
        SecError::NotSecured => crate::count(&mut c.not_secured),
        SecError::BadMic => crate::count(&mut c.bad_mic),
        SecError::UnknownKey => crate::count(&mut c.unknown_key),
        SecError::Level { .. } | SecError::NoMic => crate::count(&mut c.wrong_level),
        _ => crate::count(&mut c.malformed),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::link_keys::PeerKeys;
    use config_schema::wire::mac::{MAX_PAYLOAD, MAX_PSDU};

    const ME: u16 = 2;
    const PEER: u16 = 1;
    const PAN: u16 = 0x4242;

    fn key(generation: u32, from: u16) -> [u8; 16] {
        [generation as u8 * 16 + from as u8; 16]
    }

    fn keys(generation: u32) -> LinkKeys {
        let mut k = LinkKeys {
            generation,
            peers: Vec::new(),
        };
        k.peers
            .push(PeerKeys {
                peer: PEER,
                send: key(generation, ME),
                receive: key(generation, PEER),
            })
            .unwrap();
        k
    }

    /// A frame from PEER under generation `generation`'s key.
    fn frame(generation: u32, counter: u32, msg: &Message) -> heapless::Vec<u8, MAX_PSDU> {
        let mut payload = [0u8; MAX_PAYLOAD];
        let n = msg.emit(&mut payload).unwrap();
        let header = Header {
            seq: 0,
            pan_id: PAN,
            dst: ME,
            src: PEER,
            ack_request: false,
            secured: false,
        };
        let mut out = [0u8; MAX_PSDU];
        let len = security::secure_default(
            &header,
            &AuxRepr::new(link_key_index(generation), counter),
            &key(generation, PEER),
            ext_addr(PAN, PEER),
            &payload[..n],
            &mut out,
        )
        .unwrap();
        heapless::Vec::from_slice(&out[..len]).unwrap()
    }

    const EVENT: Message<'static> = Message::Event {
        epoch: 1,
        seq: 0,
        topic: 3,
    };

    fn verdict(
        s: &mut PeerSecurity,
        psdu: &[u8],
        now: u64,
        c: &mut SecurityCounters,
    ) -> &'static str {
        let mut scratch = [0u8; MAX_PAYLOAD];
        match s.open(psdu, ME, 0, now, &mut scratch, c) {
            Verdict::Accept(_) => "accept",
            Verdict::Challenge { .. } => "challenge",
            Verdict::Answer { .. } => "answer",
            Verdict::Answered => "answered",
            Verdict::Dropped => "dropped",
        }
    }

    /// Generation 1 running, PEER's floor at 10.
    fn running() -> (PeerSecurity, SecurityCounters) {
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        assert_eq!(
            verdict(&mut s, &frame(1, 9, &EVENT), 0, &mut c),
            "challenge"
        );
        s.challenge(PEER, 77, 0, 0);
        let answer = Message::ChallengeAnswer { nonce: 77 };
        assert_eq!(
            verdict(&mut s, &frame(1, 10, &answer), 0, &mut c),
            "answered"
        );
        (s, c)
    }

    #[test]
    fn the_previous_generation_opens_until_the_peer_is_heard_under_the_new_one() {
        let (mut s, mut c) = running();
        s.install(Some(keys(2)), &[PEER]);
        assert_eq!(
            verdict(&mut s, &frame(1, 11, &EVENT), 100, &mut c),
            "accept"
        );
        assert_eq!(
            verdict(&mut s, &frame(2, 12, &EVENT), 200, &mut c),
            "accept"
        );
        // PEER switched: its generation-1 frames are refused from now on.
        assert_eq!(
            verdict(&mut s, &frame(1, 13, &EVENT), 300, &mut c),
            "dropped"
        );
        assert_eq!(c.unknown_key, 1);
        // The floor held across the switch: a counter below it is a replay.
        assert_eq!(
            verdict(&mut s, &frame(2, 12, &EVENT), 400, &mut c),
            "dropped"
        );
        assert_eq!(c.replayed, 1);
    }

    #[test]
    fn the_previous_generation_opens_for_the_overlap_only() {
        let (mut s, mut c) = running();
        s.install(Some(keys(2)), &[PEER]);
        assert_eq!(
            verdict(&mut s, &frame(1, 11, &EVENT), 1_000, &mut c),
            "accept"
        );
        let late = 1_000 + OVERLAP_MS;
        assert_eq!(
            verdict(&mut s, &frame(1, 12, &EVENT), late, &mut c),
            "dropped"
        );
        assert_eq!(c.unknown_key, 1);
        // Two generations back is never open.
        s.install(Some(keys(3)), &[PEER]);
        assert_eq!(
            verdict(&mut s, &frame(1, 13, &EVENT), late, &mut c),
            "dropped"
        );
        assert_eq!(c.unknown_key, 2);
    }

    #[test]
    fn a_refusal_counter_at_its_limit_goes_round() {
        let mut c = SecurityCounters {
            bad_mic: u32::MAX,
            ..SecurityCounters::default()
        };
        count_refusal(SecError::BadMic, &mut c);
        count_refusal(SecError::UnknownKey, &mut c);
        assert_eq!((c.bad_mic, c.unknown_key), (0, 1));
    }

    #[test]
    fn a_forged_frame_does_not_start_the_overlap() {
        let (mut s, mut c) = running();
        s.install(Some(keys(2)), &[PEER]);
        // A frame under the previous generation's key index whose MIC is wrong (anyone
        // in range can send one) is refused; the overlap has not begun.
        let mut forged = frame(1, 11, &EVENT);
        let body = forged.len() - config_schema::wire::mac::FCS_LEN;
        forged[body - 1] ^= 0xFF;
        config_schema::wire::mac::append_fcs(&mut forged, body).unwrap();
        assert_eq!(verdict(&mut s, &forged, 0, &mut c), "dropped");
        assert_eq!(c.bad_mic, 1);
        // The peer, still on generation 1, is heard long after: its frame opens.
        let later = 5 * OVERLAP_MS;
        assert_eq!(
            verdict(&mut s, &frame(1, 12, &EVENT), later, &mut c),
            "accept"
        );
        // The overlap runs from that authentic frame.
        assert_eq!(
            verdict(&mut s, &frame(1, 13, &EVENT), later + OVERLAP_MS, &mut c),
            "dropped"
        );
        assert_eq!(c.unknown_key, 1);
    }

    #[test]
    fn a_node_that_is_no_longer_a_peer_is_forgotten_and_challenged_again() {
        let (mut s, mut c) = running();
        s.install(Some(keys(2)), &[]);
        s.install(Some(keys(3)), &[PEER]);
        assert_eq!(
            verdict(&mut s, &frame(3, 11, &EVENT), 0, &mut c),
            "challenge"
        );
    }

    #[test]
    fn challenges_are_answered_without_a_floor_and_replayed_ones_are_not() {
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        let ch = Message::Challenge { nonce: 5 };
        assert_eq!(verdict(&mut s, &frame(1, 3, &ch), 0, &mut c), "answer");
        let (mut s, mut c) = running();
        assert_eq!(verdict(&mut s, &frame(1, 3, &ch), 0, &mut c), "dropped");
        assert_eq!(c.replayed, 1);
        assert_eq!(verdict(&mut s, &frame(1, 30, &ch), 0, &mut c), "answer");
    }

    #[test]
    fn a_challenge_from_a_peer_of_unknown_floor_is_answered_and_challenged_back_once() {
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        let ch = Message::Challenge { nonce: 5 };
        let mut scratch = [0u8; MAX_PAYLOAD];
        let v = s.open(&frame(1, 3, &ch), ME, 0, 0, &mut scratch, &mut c);
        assert!(matches!(
            v,
            Verdict::Answer {
                peer: PEER,
                nonce: 5,
                answer: true,
                challenge: true,
                renumber: true,
            }
        ));
        // A newer challenge within the handshake's rate: neither answered nor challenged
        // again, the link numbered again.
        let newer = Message::Challenge { nonce: 6 };
        let v = s.open(
            &frame(1, 4, &newer),
            ME,
            0,
            ANSWER_MS - 1,
            &mut scratch,
            &mut c,
        );
        assert!(matches!(
            v,
            Verdict::Answer {
                answer: false,
                challenge: false,
                renumber: true,
                ..
            }
        ));
        // A copy of that challenge (the radio duplicated it), an older one replayed, or
        // a retry of the peer's (its nonce repeated in a newer frame): answered at the
        // handshake's rate, the link numbered again if it took events of its epoch
        // (`NodeCore::renumber_link`); a reset's greeting numbers nothing again.
        let reset = Message::Challenge {
            nonce: crate::restart::RESET_GREETING,
        };
        for (counter, ch, renumbers) in [(4, &newer, true), (2, &ch, true), (9, &reset, false)] {
            let v = s.open(
                &frame(1, counter, ch),
                ME,
                0,
                10 * ANSWER_MS,
                &mut scratch,
                &mut c,
            );
            assert!(
                matches!(v, Verdict::Answer { renumber, .. } if renumber == renumbers),
                "counter {counter}"
            );
        }
    }

    /// Until a peer answers, every challenge to it within [`REPEAT_MS`] of the first
    /// repeats its nonce (a greeting's flag kept, and added if a greeting follows another
    /// challenge); after that time, once the peer answered, or once a new table runs, a
    /// challenge has its frame's counter again.
    #[test]
    fn a_challenge_repeats_the_nonce_of_the_one_not_answered_yet_for_a_while() {
        use crate::restart::GREETING;
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        assert_eq!(s.challenge(PEER, 7, GREETING, 0), 7 | GREETING);
        assert_eq!(s.challenge(PEER, 8, GREETING, 100), 7 | GREETING);
        assert_eq!(s.challenge(PEER, 9, 0, 150), 7 | GREETING);
        assert_eq!(
            s.challenge(PEER, 10, 0, REPEAT_MS),
            10,
            "repeated for a while only"
        );
        assert_eq!(
            s.challenge(PEER, 11, GREETING, REPEAT_MS + 1),
            10 | GREETING
        );
        s.install(Some(keys(1)), &[PEER]);
        assert_eq!(
            s.challenge(PEER, 12, 0, REPEAT_MS + 2),
            12,
            "a new table starts afresh"
        );
        let answer = Message::ChallengeAnswer { nonce: 12 };
        assert_eq!(
            verdict(&mut s, &frame(1, 40, &answer), 0, &mut c),
            "answered"
        );
        assert_eq!(s.challenge(PEER, 13, 0, REPEAT_MS + 3), 13, "answered");
    }

    #[test]
    fn keys_installed_greet_every_peer_without_a_floor_once() {
        let (mut s, _) = running();
        s.install(Some(keys(2)), &[PEER]);
        assert_eq!(s.next_greeting(0), None, "its floor is known");
        let mut s = PeerSecurity::default();
        s.install(Some(keys(1)), &[PEER]);
        assert_eq!(s.greeting(), Some(0));
        let tries: Vec<u64, 8> = (0..20 * GREET_EVERY_MS)
            .filter(|&t| s.next_greeting(t) == Some(PEER))
            .collect();
        assert_eq!(
            tries,
            [0, 100, 200, 300, 400],
            "until answered, 5 times at most"
        );
        assert_eq!(s.greeting(), None);
        s.install(Some(keys(2)), &[PEER]);
        assert_eq!(s.next_greeting(1_000), Some(PEER));
        // Answered: no more greetings.
        s.challenge(PEER, 77, 0, 1_000);
        let mut c = SecurityCounters::default();
        let answer = Message::ChallengeAnswer { nonce: 77 };
        assert_eq!(
            verdict(&mut s, &frame(2, 10, &answer), 1_001, &mut c),
            "answered"
        );
        assert_eq!(s.next_greeting(1_000 + GREET_EVERY_MS), None);
        s.install(None, &[PEER]);
        assert_eq!(s.greeting(), None, "no keys, no greeting");
    }

    #[test]
    fn a_frame_of_the_staged_generation_is_dropped_uncounted() {
        let (mut s, mut c) = running();
        let mut scratch = [0u8; MAX_PAYLOAD];
        let early = frame(2, 20, &EVENT);
        assert!(matches!(
            s.open(&early, ME, 2, 0, &mut scratch, &mut c),
            Verdict::Dropped
        ));
        assert_eq!(c.unknown_key, 0, "a peer that switched a moment earlier");
        assert!(matches!(
            s.open(&early, ME, 0, 0, &mut scratch, &mut c),
            Verdict::Dropped
        ));
        assert_eq!(c.unknown_key, 1, "nothing staged: an unknown key");
    }

    #[test]
    fn an_answer_to_the_challenge_before_the_last_still_sets_the_floor() {
        // On a busy medium the answer to one challenge can arrive after the next was
        // sent: it proves freshness as well (before, every answer came one challenge late,
        // and two nodes of the eight-actuator robot challenged each other for a minute).
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        // (Each after the last one's nonce is no longer repeated.)
        s.challenge(PEER, 77, 0, 0);
        s.challenge(PEER, 78, 0, REPEAT_MS);
        let late = Message::ChallengeAnswer { nonce: 77 };
        assert_eq!(verdict(&mut s, &frame(1, 10, &late), 0, &mut c), "answered");
        assert_eq!(verdict(&mut s, &frame(1, 11, &EVENT), 0, &mut c), "accept");
        // Only the last two count, and each once.
        let mut s = PeerSecurity::default();
        s.install(Some(keys(1)), &[PEER]);
        for (nonce, at) in [(77, 0), (78, REPEAT_MS), (79, 2 * REPEAT_MS)] {
            s.challenge(PEER, nonce, 0, at);
        }
        let oldest = Message::ChallengeAnswer { nonce: 77 };
        assert_eq!(
            verdict(&mut s, &frame(1, 10, &oldest), 0, &mut c),
            "challenge"
        );
    }

    #[test]
    fn a_peer_is_challenged_at_half_the_rate_it_answers() {
        // A peer's answer is never held back by its own rate limit: a challenge comes at
        // most every CHALLENGE_MS, twice the interval of answers.
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        let mut scratch = [0u8; MAX_PAYLOAD];
        let challenged: Vec<bool, 8> = [0, ANSWER_MS, CHALLENGE_MS - 1, CHALLENGE_MS]
            .iter()
            .zip(20..)
            .map(|(&t, counter)| {
                match s.open(&frame(1, counter, &EVENT), ME, 0, t, &mut scratch, &mut c) {
                    Verdict::Challenge { challenge, .. } => challenge,
                    _ => panic!("no floor: challenged"),
                }
            })
            .collect();
        assert_eq!(challenged, [true, false, false, true]);
        let mut s = PeerSecurity::default();
        s.install(Some(keys(1)), &[PEER]);
        let answered: Vec<bool, 8> = [0, ANSWER_MS - 1, ANSWER_MS]
            .iter()
            .zip(20..)
            .map(|(&t, counter)| {
                let ch = Message::Challenge { nonce: counter };
                match s.open(&frame(1, counter, &ch), ME, 0, t, &mut scratch, &mut c) {
                    Verdict::Answer { answer, .. } => answer,
                    _ => panic!("a challenge is answered"),
                }
            })
            .collect();
        assert_eq!(answered, [true, false, true]);
    }

    #[test]
    fn an_answer_that_comes_long_after_its_challenge_does_not_set_the_floor() {
        // An answer captured and kept from the node (its floor never set) and sent later
        // would set an old floor: the peer's frames above it, refused while there was no
        // floor, could then be replayed and acted on.
        let answer = Message::ChallengeAnswer { nonce: 77 };
        let mut c = SecurityCounters::default();
        let late = ANSWER_WITHIN_MS + ANSWER_TICK_MS;
        for (at, verdict_then) in [(ANSWER_WITHIN_MS, "answered"), (late, "challenge")] {
            let mut s = PeerSecurity::default();
            s.install(Some(keys(1)), &[PEER]);
            s.challenge(PEER, 77, 0, 0);
            assert_eq!(
                verdict(&mut s, &frame(1, 10, &answer), at, &mut c),
                verdict_then
            );
        }
        // A repeated nonce is as fresh as its last challenge.
        let mut s = PeerSecurity::default();
        s.install(Some(keys(1)), &[PEER]);
        s.challenge(PEER, 77, 0, 0);
        assert_eq!(s.challenge(PEER, 78, 0, REPEAT_MS - 1), 77);
        let at = REPEAT_MS - 1 + ANSWER_WITHIN_MS;
        assert_eq!(
            verdict(&mut s, &frame(1, 10, &answer), at, &mut c),
            "answered"
        );
        // A challenge sent later does not make an old one's answer fresh again (a frame
        // of the peer replayed to provoke it): the old nonce is dropped.
        let mut s = PeerSecurity::default();
        s.install(Some(keys(1)), &[PEER]);
        s.challenge(PEER, 77, 0, 0);
        s.challenge(PEER, 78, 0, late);
        assert_eq!(
            verdict(&mut s, &frame(1, 10, &answer), late, &mut c),
            "challenge"
        );
    }

    /// The floor an answer sets is at least the highest counter of the peer's authentic
    /// frames come while it had none (a challenge, an event not acted on): an answer the
    /// peer sent before it booted again, come late, sets no floor below its new life's.
    #[test]
    fn an_answer_sets_the_floor_at_least_at_what_the_peer_sent_before_it() {
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        s.challenge(PEER, 77, 0, 0);
        let greeting = Message::Challenge { nonce: 50 };
        assert_eq!(
            verdict(&mut s, &frame(1, 50, &greeting), 0, &mut c),
            "answer"
        );
        assert_eq!(
            verdict(&mut s, &frame(1, 40, &EVENT), 0, &mut c),
            "challenge"
        );
        let old = Message::ChallengeAnswer { nonce: 77 };
        assert_eq!(verdict(&mut s, &frame(1, 30, &old), 0, &mut c), "answered");
        for (counter, want) in [(31, "dropped"), (50, "dropped"), (51, "accept")] {
            assert_eq!(
                verdict(&mut s, &frame(1, counter, &EVENT), 0, &mut c),
                want,
                "counter {counter}"
            );
        }
    }

    #[test]
    fn a_wrong_nonce_does_not_set_the_floor() {
        let mut s = PeerSecurity::default();
        let mut c = SecurityCounters::default();
        s.install(Some(keys(1)), &[PEER]);
        s.challenge(PEER, 77, 0, 0);
        let wrong = Message::ChallengeAnswer { nonce: 78 };
        assert_eq!(
            verdict(&mut s, &frame(1, 10, &wrong), 0, &mut c),
            "challenge"
        );
        assert_eq!(
            verdict(&mut s, &frame(1, 11, &EVENT), 0, &mut c),
            "challenge"
        );
    }
}
