//! The visited set's form of a state: a [`Sys`] packed into a few bytes (about 10 a node,
//! where the working form holds 150 and five heap blocks), so that a search keeps millions
//! of states in a fraction of the memory and hashes a short key.
//!
//! The encoding is a function of the state alone and [`unpack_into`] inverts it, so two states
//! are equal exactly when their packed bytes are: the set compares bytes. Integers are
//! LEB128 varints (signed ones zigzagged first), lists carry their length, and the fixed
//! arrays of an [`EngineState`] drop their trailing zeros (a table of one chart and two
//! variables packs two short lists, not 8 and 32 entries).

use config_schema::limits::{MAX_CHARTS, MAX_VARS};
use node_fw::cylinder::Position as Pos;
use node_fw::ecc::{EngineState, Fault};
use robot_compiler::automata::StateSet;

use super::feed::{Balls, Front};
use super::motor::Region;
use super::place::Place;
use super::Sys;
use crate::automata::Config;

/// `s`, packed into `out` (cleared first).
pub(super) fn pack(s: &Sys, out: &mut Vec<u8>) {
    out.clear();
    let mut w = Writer(out);
    w.len(s.nodes.len());
    for e in &s.nodes {
        w.engine(e);
    }
    w.bytes(&s.timers);
    w.len(s.pos.len());
    for p in &s.pos {
        w.u8(match p {
            Place::Rod(Pos::Home) => 0,
            Place::Rod(Pos::End) => 1,
            Place::Rod(Pos::Extending) => 2,
            Place::Rod(Pos::Retracting) => 3,
            Place::Between => 4,
        });
    }
    w.len(s.flight.len());
    for &(link, topic) in &s.flight {
        w.u8(link);
        w.u8(topic);
    }
    w.uint(s.alarms);
    w.uint(u64::from(s.progress));
    w.u8(match s.homing {
        None => 0,
        Some(false) => 1,
        Some(true) => 2,
    });
    match &s.ball {
        None => w.u8(0),
        Some(b) => {
            w.u8(1);
            w.balls(b);
        }
    }
    match s.estop {
        None => w.u8(0),
        Some(e) => {
            w.u8(1);
            w.u8(e);
        }
    }
    w.len(s.regions.len());
    for r in &s.regions {
        w.u8(match r {
            Region::Home => 0,
            Region::Between => 1,
            Region::End => 2,
        });
    }
    w.u8(s.switches);
    w.u8(s.sets);
    w.u8(s.latched);
    w.u8(u8::from(s.uncleared));
}

/// The state `bytes` were packed from, unpacked into `s`, each of its lists refilled in
/// place (`None`: `bytes` were not made by [`pack`]; `s` is then partly overwritten).
pub(super) fn unpack_into(bytes: &[u8], s: &mut Sys) -> Option<()> {
    let mut r = Reader(bytes);
    r.list_into(&mut s.nodes, Reader::engine)?;
    r.list_into(&mut s.timers, Reader::u8)?;
    r.list_into(&mut s.pos, |r| {
        Some(match r.u8()? {
            0 => Place::Rod(Pos::Home),
            1 => Place::Rod(Pos::End),
            2 => Place::Rod(Pos::Extending),
            3 => Place::Rod(Pos::Retracting),
            4 => Place::Between,
            _ => return None,
        })
    })?;
    r.list_into(&mut s.flight, |r| Some((r.u8()?, r.u8()?)))?;
    s.alarms = r.uint()?;
    s.progress = u16::try_from(r.uint()?).ok()?;
    s.homing = match r.u8()? {
        0 => None,
        1 => Some(false),
        2 => Some(true),
        _ => return None,
    };
    s.ball = match r.u8()? {
        0 => None,
        1 => Some(r.balls()?),
        _ => return None,
    };
    s.estop = match r.u8()? {
        0 => None,
        1 => Some(r.u8()?),
        _ => return None,
    };
    r.list_into(&mut s.regions, |r| {
        Some(match r.u8()? {
            0 => Region::Home,
            1 => Region::Between,
            2 => Region::End,
            _ => return None,
        })
    })?;
    s.switches = r.u8()?;
    s.sets = r.u8()?;
    s.latched = r.u8()?;
    s.uncleared = match r.u8()? {
        0 => false,
        1 => true,
        _ => return None,
    };
    r.0.is_empty().then_some(())
}

struct Writer<'o>(&'o mut Vec<u8>);

impl Writer<'_> {
    fn u8(&mut self, b: u8) {
        self.0.push(b);
    }

    /// LEB128: seven bits a byte, low first, the top bit set on every byte but the last.
    fn uint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.0.push(v as u8 | 0x80);
            v >>= 7;
        }
        self.0.push(v as u8);
    }

    fn int(&mut self, v: i32) {
        self.uint(u64::from(((v << 1) ^ (v >> 31)) as u32));
    }

    fn len(&mut self, n: usize) {
        self.uint(n as u64);
    }

    fn bytes(&mut self, b: &[u8]) {
        self.len(b.len());
        self.0.extend_from_slice(b);
    }

    fn engine(&mut self, e: &EngineState) {
        self.bytes(trimmed(&e.current));
        let vars = trimmed(&e.vars);
        self.len(vars.len());
        for &v in vars {
            self.int(v);
        }
        self.uint(u64::from(e.inputs));
        self.uint(u64::from(e.outputs));
        match e.fault {
            None => self.u8(0),
            Some(Fault::ChainLimit { chart }) => {
                self.u8(1);
                self.u8(chart);
            }
            Some(Fault::QueueFull { event }) => {
                self.u8(2);
                self.u8(event);
            }
            Some(Fault::Cascade { event }) => {
                self.u8(3);
                self.u8(event);
            }
            Some(Fault::Action { chart, code }) => {
                self.u8(4);
                self.u8(chart);
                self.u8(code);
            }
            Some(Fault::Expr { chart }) => {
                self.u8(5);
                self.u8(chart);
            }
        }
    }

    fn balls(&mut self, b: &Balls) {
        self.u8(b.count);
        match b.front {
            Front::Ball(colour) => {
                self.u8(0);
                self.u8(colour);
            }
            Front::Gone => self.u8(1),
            Front::Empty => self.u8(2),
        }
        match b.shaft {
            None => self.u8(0),
            Some((ball, colour, at)) => {
                self.u8(1);
                self.0.extend_from_slice(&[ball, colour, at]);
            }
        }
        self.u8(b.took);
        self.u8(b.eos);
        self.len(b.refs.len());
        for c in &b.refs {
            self.uint(c.active.0);
            self.len(c.counts.len());
            for &n in &c.counts {
                self.uint(u64::from(n));
            }
        }
    }
}

/// `a` without its trailing zeros (the default value), skipped eight at a time first:
/// an engine's arrays are mostly a few values, then zeros.
fn trimmed<T: Default + PartialEq>(a: &[T]) -> &[T] {
    let zero = T::default();
    let mut n = a.len();
    while n >= 8 && a[n - 8..n].iter().all(|x| *x == zero) {
        n -= 8;
    }
    while n > 0 && a[n - 1] == zero {
        n -= 1;
    }
    &a[..n]
}

struct Reader<'b>(&'b [u8]);

impl Reader<'_> {
    fn u8(&mut self) -> Option<u8> {
        let (&b, rest) = self.0.split_first()?;
        self.0 = rest;
        Some(b)
    }

    fn uint(&mut self) -> Option<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8()?;
            v |= u64::from(b & 0x7f).checked_shl(shift)?;
            if b & 0x80 == 0 {
                return Some(v);
            }
        }
        None
    }

    fn int(&mut self) -> Option<i32> {
        let z = u32::try_from(self.uint()?).ok()?;
        Some((z >> 1) as i32 ^ -((z & 1) as i32))
    }

    fn len(&mut self) -> Option<usize> {
        usize::try_from(self.uint()?).ok()
    }

    /// A list: its length, then each entry as `entry` reads it.
    fn list<T>(&mut self, entry: impl Fn(&mut Self) -> Option<T>) -> Option<Vec<T>> {
        let mut v = Vec::new();
        self.list_into(&mut v, entry)?;
        Some(v)
    }

    /// [`Reader::list`] into `v` (emptied first, its room kept).
    fn list_into<T>(
        &mut self,
        v: &mut Vec<T>,
        entry: impl Fn(&mut Self) -> Option<T>,
    ) -> Option<()> {
        let n = self.len()?;
        v.clear();
        // Every entry takes a byte at least: no more room than the bytes left.
        v.reserve(n.min(self.0.len()));
        for _ in 0..n {
            v.push(entry(self)?);
        }
        Some(())
    }

    fn slice(&mut self) -> Option<&[u8]> {
        let n = self.len()?;
        let (b, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(b)
    }

    fn engine(&mut self) -> Option<EngineState> {
        let mut current = [0u8; MAX_CHARTS];
        let charts = self.slice()?;
        current.get_mut(..charts.len())?.copy_from_slice(charts);
        let mut vars = [0i32; MAX_VARS];
        let n = self.len()?;
        for v in vars.get_mut(..n)? {
            *v = self.int()?;
        }
        let inputs = u16::try_from(self.uint()?).ok()?;
        let outputs = u16::try_from(self.uint()?).ok()?;
        let fault = match self.u8()? {
            0 => None,
            1 => Some(Fault::ChainLimit { chart: self.u8()? }),
            2 => Some(Fault::QueueFull { event: self.u8()? }),
            3 => Some(Fault::Cascade { event: self.u8()? }),
            4 => Some(Fault::Action {
                chart: self.u8()?,
                code: self.u8()?,
            }),
            5 => Some(Fault::Expr { chart: self.u8()? }),
            _ => return None,
        };
        Some(EngineState {
            current,
            vars,
            inputs,
            outputs,
            fault,
        })
    }

    fn balls(&mut self) -> Option<Balls> {
        let count = self.u8()?;
        let front = match self.u8()? {
            0 => Front::Ball(self.u8()?),
            1 => Front::Gone,
            2 => Front::Empty,
            _ => return None,
        };
        let shaft = match self.u8()? {
            0 => None,
            1 => Some((self.u8()?, self.u8()?, self.u8()?)),
            _ => return None,
        };
        let took = self.u8()?;
        let eos = self.u8()?;
        let refs = self.list(|r| {
            let active = StateSet(r.uint()?);
            let counts = r.list(|r| u32::try_from(r.uint()?).ok())?;
            Some(Config { active, counts })
        })?;
        Some(Balls {
            count,
            front,
            shaft,
            took,
            eos,
            refs,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::collections::{HashSet, VecDeque};

    use robot_compiler::{compile, Compiled, Source};

    use super::super::{homing, ExploreOptions, Model, Search};
    use super::*;

    fn unpack(bytes: &[u8]) -> Option<Sys> {
        let mut s = Sys::default();
        unpack_into(bytes, &mut s).map(|()| s)
    }

    fn robot(name: &str) -> Compiled {
        let path = format!("{}/../robot-configs/{name}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        compile(&Source::new(&path, text)).unwrap()
    }

    /// Every state reachable from `roots`, found with the states themselves as the keys
    /// (the visited set before packing), in breadth-first order, with how many there are.
    fn unpacked_bfs(
        model: &Model<'_>,
        roots: &[(Sys, Option<String>)],
        opts: ExploreOptions,
    ) -> Vec<Sys> {
        let mut seen = HashSet::new();
        let mut order = Vec::new();
        let mut queue: VecDeque<Sys> = VecDeque::new();
        for (root, _) in roots {
            if seen.insert(root.clone()) {
                queue.push_back(root.clone());
                order.push(root.clone());
            }
        }
        let mut moves = Vec::new();
        while let Some(s) = queue.pop_front() {
            model.moves(&s, opts, &mut moves);
            for &m in &moves {
                let mut t = s.clone();
                if model.apply(&mut t, m, None).is_some() {
                    continue;
                }
                if seen.insert(t.clone()) {
                    queue.push_back(t.clone());
                    order.push(t);
                }
            }
        }
        order
    }

    /// The packed search finds exactly the states, in the same order, that the search
    /// keyed by the states themselves finds, and every one unpacks to itself: on the
    /// paint robot's cycle (lossless and lossy links) and homing (rods between their
    /// switches), the ball sorter's feed and the transport's motors and switches.
    #[test]
    fn the_packed_search_finds_exactly_the_states_of_the_unpacked_one() {
        let plain = ExploreOptions::default();
        let lossy = ExploreOptions {
            lossy: true,
            ..plain
        };
        let prompt = ExploreOptions {
            prompt: true,
            ..plain
        };
        let paint = robot("paint-robot.ron");
        let sorter = robot("ball-sorter.ron");
        let transport = robot("waterjet-transport.ron");
        let mut checked = 0;
        // Whether some state had each field away from its empty value.
        let mut covered = [false; 11];
        for (c, opts) in [
            (&paint, vec![plain, lossy]),
            (&sorter, vec![plain]),
            (&transport, vec![prompt]),
        ] {
            let model = Model::new(c).unwrap();
            let mut runs: Vec<_> = opts.into_iter().map(|o| (model.roots(), o)).collect();
            if model.home.is_some() {
                runs.push((homing::roots(&model).collect(), plain));
            }
            for (roots, opts) in runs {
                let want = unpacked_bfs(&model, &roots, opts);
                let got = Search::bfs(&model, roots, opts);
                assert!(got.violation.is_none() && !got.incomplete);
                assert_eq!(got.seen.len(), want.len());
                let mut key = Vec::new();
                for (i, s) in want.iter().enumerate() {
                    assert_eq!(got.state(i).as_ref(), Some(s), "state {i}");
                    pack(s, &mut key);
                    assert_eq!(got.seen.get_index(i).map(|b| &b[..]), Some(&key[..]));
                }
                checked += want.len();
                for s in &want {
                    let fields = [
                        s.nodes.iter().any(|e| e.fault.is_some()),
                        s.nodes.iter().any(|e| e.vars.iter().any(|&v| v != 0)),
                        s.timers.iter().any(|&t| t != 0),
                        s.pos.contains(&Place::Between),
                        !s.flight.is_empty(),
                        s.alarms != 0,
                        s.homing.is_some(),
                        s.ball.as_ref().is_some_and(|b| b.shaft.is_some()),
                        s.regions.contains(&Region::Between),
                        s.switches != 0,
                        s.latched != 0,
                    ];
                    for (seen, field) in covered.iter_mut().zip(fields) {
                        *seen |= field;
                    }
                }
            }
        }
        assert!(checked > 10_000, "{checked} states");
        assert_eq!(covered, [true; 11]);
    }

    fn engine() -> EngineState {
        let mut vars = [0; MAX_VARS];
        vars[0] = 1;
        vars[2] = -65;
        EngineState {
            current: [3, 0, 2, 0, 0, 0, 0, 0],
            vars,
            inputs: 0x0102,
            outputs: 0x80,
            fault: Some(Fault::Action { chart: 1, code: 7 }),
        }
    }

    fn sys() -> Sys {
        Sys {
            nodes: vec![engine()],
            timers: vec![5],
            pos: vec![Place::Rod(Pos::Retracting), Place::Between],
            flight: vec![(1, 9)],
            alarms: 1 << 9,
            progress: 300,
            homing: Some(true),
            ball: Some(Balls {
                count: 2,
                front: Front::Ball(1),
                shaft: Some((2, 0, 3)),
                took: 1,
                eos: 0,
                refs: vec![Config {
                    active: StateSet(0b101),
                    counts: vec![0, 200],
                }],
            }),
            estop: Some(1),
            regions: vec![Region::End],
            switches: 0b10,
            sets: 1,
            latched: 0,
            uncleared: true,
        }
    }

    /// The bytes of one state, field by field.
    #[test]
    fn a_state_packs_to_these_bytes() {
        let mut out = Vec::new();
        pack(&sys(), &mut out);
        #[rustfmt::skip]
        let want = [
            1, // one node:
            3, 3, 0, 2, // charts: three (trailing zeros dropped), states 3, 0, 2
            3, 2, 0, 129, 1, // variables: three, zigzagged: 1, 0, -65
            130, 2, 128, 1, // inputs 0x102, outputs 0x80 (varints)
            4, 1, 7, // fault: an action's, chart 1, code 7
            1, 5, // timers: one byte, 5
            2, 3, 4, // places: retracting, between
            1, 1, 9, // in flight: link 1, topic 9
            128, 4, // alarms: bit 9
            172, 2, // progress 300
            2, // homing, HOME given
            1, 2, 0, 1, 1, 2, 0, 3, 1, 0, // balls: count, front ball 1, shaft, took, eos
            1, 5, 2, 0, 200, 1, // one automaton: active {0, 2}, counts 0, 200
            1, 1, // e-stop 1
            1, 2, // regions: end
            2, 1, 0, 1, // switches, sets, latched, uncleared
        ];
        assert_eq!(out, want);
        assert_eq!(unpack(&out), Some(sys()));
    }

    mod any {
        use proptest::collection::vec;
        use proptest::prelude::*;

        use super::*;

        fn fault() -> impl Strategy<Value = Option<Fault>> {
            prop_oneof![
                Just(None),
                any::<u8>().prop_map(|chart| Some(Fault::ChainLimit { chart })),
                any::<u8>().prop_map(|event| Some(Fault::QueueFull { event })),
                any::<u8>().prop_map(|event| Some(Fault::Cascade { event })),
                (any::<u8>(), any::<u8>())
                    .prop_map(|(chart, code)| Some(Fault::Action { chart, code })),
                any::<u8>().prop_map(|chart| Some(Fault::Expr { chart })),
            ]
        }

        /// Mostly zeros, as an engine's arrays are, and any value.
        fn int() -> impl Strategy<Value = i32> {
            prop_oneof![3 => Just(0), 1 => any::<i32>(), 1 => -300..300]
        }

        fn engine() -> impl Strategy<Value = EngineState> {
            let current = proptest::array::uniform8(prop_oneof![3 => Just(0u8), 1 => any::<u8>()]);
            let vars = proptest::array::uniform32(int());
            (current, vars, any::<u16>(), any::<u16>(), fault()).prop_map(
                |(current, vars, inputs, outputs, fault)| EngineState {
                    current,
                    vars,
                    inputs,
                    outputs,
                    fault,
                },
            )
        }

        fn place() -> impl Strategy<Value = Place> {
            prop_oneof![
                Just(Place::Rod(Pos::Home)),
                Just(Place::Rod(Pos::End)),
                Just(Place::Rod(Pos::Extending)),
                Just(Place::Rod(Pos::Retracting)),
                Just(Place::Between),
            ]
        }

        fn balls() -> impl Strategy<Value = Option<Balls>> {
            let front = prop_oneof![
                any::<u8>().prop_map(Front::Ball),
                Just(Front::Gone),
                Just(Front::Empty)
            ];
            let config = (any::<u64>(), vec(any::<u32>(), 0..4)).prop_map(|(a, counts)| Config {
                active: StateSet(a),
                counts,
            });
            let balls = (
                any::<u8>(),
                front,
                proptest::option::of(any::<(u8, u8, u8)>()),
                any::<(u8, u8)>(),
                vec(config, 0..3),
            )
                .prop_map(|(count, front, shaft, (took, eos), refs)| Balls {
                    count,
                    front,
                    shaft,
                    took,
                    eos,
                    refs,
                });
            proptest::option::of(balls)
        }

        prop_compose! {
            pub fn sys()(
                nodes in vec(engine(), 0..9),
                timers in vec(any::<u8>(), 0..9),
                pos in vec(place(), 0..9),
                flight in vec(any::<(u8, u8)>(), 0..9),
                alarms in any::<u64>(),
                progress in any::<u16>(),
                homing in proptest::option::of(any::<bool>()),
                ball in balls(),
                estop in proptest::option::of(any::<u8>()),
                regions in vec(prop_oneof![Just(Region::Home), Just(Region::Between), Just(Region::End)], 0..4),
                (switches, sets, latched, uncleared) in any::<(u8, u8, u8, bool)>(),
            ) -> Sys {
                Sys { nodes, timers, pos, flight, alarms, progress, homing, ball, estop, regions, switches, sets, latched, uncleared }
            }
        }
    }

    proptest::proptest! {
        /// Any state, at the edges of every field too, unpacks to itself, also into the
        /// lists of another state; two states pack to the same bytes exactly when they are
        /// equal.
        #[test]
        fn any_state_unpacks_to_itself_and_packs_apart_from_any_other(
            a in any::sys(),
            b in any::sys(),
        ) {
            let (mut ka, mut kb) = (Vec::new(), Vec::new());
            pack(&a, &mut ka);
            pack(&b, &mut kb);
            proptest::prop_assert_eq!(unpack(&ka), Some(a.clone()));
            let mut into = b.clone();
            proptest::prop_assert_eq!(unpack_into(&ka, &mut into), Some(()));
            proptest::prop_assert_eq!(&into, &a);
            proptest::prop_assert_eq!(ka == kb, a == b);
        }
    }

    /// Bytes that no state packs to unpack to nothing: every cut of a packed state, one
    /// byte more, a tag out of range, a count past an engine's arrays.
    #[test]
    fn bytes_no_state_packs_to_unpack_to_nothing() {
        let mut out = Vec::new();
        pack(&sys(), &mut out);
        for n in 0..out.len() {
            assert_eq!(unpack(&out[..n]), None, "cut at {n}");
        }
        let mut longer = out.clone();
        longer.push(0);
        assert_eq!(unpack(&longer), None);
        let mut bad = out.clone();
        bad[14] = 6; // no such fault
        assert_eq!(unpack(&bad), None);
        // Nine charts, 33 variables, a varint of eleven bytes.
        assert_eq!(unpack(&[1, 9, 0, 0, 0, 0, 0, 0, 0, 0, 0]), None);
        assert_eq!(unpack(&[1, 0, 33]), None);
        assert_eq!(unpack(&[0x80; 11]), None);
    }
}
