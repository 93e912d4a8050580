//! `btrel fit` on BehaviorTree.CPP SqliteLogger databases.
//!
//! behaviortreepy (the BT.CPP v4 wheel) exposes FileLogger and
//! StdCoutLogger but not SqliteLogger, so these tests write the databases
//! themselves, in the exact schema of BT.CPP's `bt_sqlite_logger.cpp` (4.6+,
//! and the `uid` column of 4.1–4.5), the way its logger fills them: a
//! `Definitions` row and `Nodes` rows per session, one `Transitions` row per
//! status change (IDLE included) with a strictly increasing µs timestamp.
//! Expected values are hand calculations and the CSV reader, fed the same
//! episodes.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use btrel::fit::{fit_logs, By, Timing};
use btrel::logs::{read_logs, End};
use rusqlite::{params, Connection};

fn bin() -> assert_cmd::Command {
    assert_cmd::Command::cargo_bin("btrel").expect("binary")
}

const IDLE: u8 = 0;
const RUN: u8 = 1;
const OK: u8 = 2;
const FAIL: u8 = 3;
/// 1 s in µs.
const S: i64 = 1_000_000;
/// An absolute start: µs since the epoch, as BT.CPP logs by default.
const T0: i64 = 1_700_000_000 * S;

/// BT.CPP 4.6+ (`bt_sqlite_logger.cpp`), verbatim.
const SCHEMA: &str = "CREATE TABLE IF NOT EXISTS Transitions (\
    timestamp  INTEGER PRIMARY KEY NOT NULL, \
    session_id INTEGER NOT NULL, \
    node_uid   INTEGER NOT NULL, \
    duration   INTEGER, \
    state      INTEGER NOT NULL,\
    extra_data VARCHAR );\
    CREATE TABLE IF NOT EXISTS Nodes (\
    session_id INTEGER NOT NULL, \
    fullpath   VARCHAR, \
    node_uid   INTEGER NOT NULL );\
    CREATE TABLE IF NOT EXISTS Definitions (\
    session_id INTEGER PRIMARY KEY AUTOINCREMENT, \
    date       TEXT NOT NULL,\
    xml_tree   TEXT NOT NULL);";

/// Sequence(a: A, c: C, a2: A, b: B), uids 1..5, as WriteTreeToXML writes it.
const XML: &str = r#"<root BTCPP_format="4">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence name="seq" _uid="1" _fullpath="seq::1">
      <A name="a" _uid="2" _fullpath="a::2"/>
      <C name="c" _uid="3" _fullpath="c::3"/>
      <A name="a2" _uid="4" _fullpath="a2::4"/>
      <B name="b" _uid="5" _fullpath="b::5"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel>
    <Action ID="A"/>
    <Action ID="B"/>
    <Condition ID="C"/>
  </TreeNodesModel>
</root>"#;

/// The same tree with other uids (a later session of another build).
const XML2: &str = r#"<root BTCPP_format="4">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence name="seq" _uid="10" _fullpath="seq::10">
      <A name="a" _uid="14" _fullpath="a::14"/>
      <C name="c" _uid="13" _fullpath="c::13"/>
      <A name="a2" _uid="12" _fullpath="a2::12"/>
      <B name="b" _uid="11" _fullpath="b::11"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel>
    <Action ID="A"/>
    <Action ID="B"/>
    <Condition ID="C"/>
  </TreeNodesModel>
</root>"#;

/// Writes a database the way BT.CPP's SqliteLogger does.
struct Logger {
    db: Connection,
    session: i64,
    last: i64,
    started: HashMap<u16, i64>,
    status: HashMap<u16, u8>,
}

impl Logger {
    fn create(path: &Path) -> Logger {
        Logger::with_schema(path, SCHEMA)
    }
    fn with_schema(path: &Path, schema: &str) -> Logger {
        let db = Connection::open(path).unwrap();
        // fast writes (the file format is the same)
        db.execute_batch("PRAGMA synchronous = OFF; PRAGMA journal_mode = MEMORY;")
            .unwrap();
        db.execute_batch(schema).unwrap();
        Logger {
            db,
            session: 0,
            last: i64::MIN,
            started: HashMap::new(),
            status: HashMap::new(),
        }
    }
    /// A new session (append mode): its tree and nodes.
    fn session(&mut self, xml: &str, uids: &[u16]) {
        self.db
            .execute(
                "INSERT into Definitions (date, xml_tree) VALUES (datetime('now','localtime'),?)",
                [xml],
            )
            .unwrap();
        self.session = self
            .db
            .query_row("SELECT MAX(session_id) FROM Definitions", [], |r| r.get(0))
            .unwrap();
        for &u in uids {
            self.db
                .execute(
                    "INSERT INTO Nodes VALUES (?, ?, ?)",
                    params![self.session, format!("n::{u}"), u],
                )
                .unwrap();
        }
        self.started.clear();
        self.status.clear();
    }
    /// One status change at (about) `t` µs: the logger's timestamps are
    /// strictly increasing, `duration` is set when RUNNING ends.
    fn change(&mut self, t: i64, uid: u16, state: u8) {
        let ts = t.max(self.last.saturating_add(1));
        self.last = ts;
        let prev = self.status.insert(uid, state).unwrap_or(IDLE);
        if prev == IDLE && state == RUN {
            self.started.insert(uid, ts);
        }
        let duration = if prev == RUN && state != RUN {
            ts - self.started.get(&uid).copied().unwrap_or(ts)
        } else {
            0
        };
        self.db
            .execute(
                "INSERT INTO Transitions VALUES (?, ?, ?, ?, ?, '')",
                params![ts, self.session, uid, duration, state],
            )
            .unwrap();
    }
    /// IDLE → RUNNING at `t`, then `end` (SUCCESS, FAILURE, or IDLE: a halt)
    /// after `d` µs, then IDLE.
    fn episode(&mut self, t: i64, uid: u16, d: i64, end: u8) {
        self.change(t, uid, RUN);
        self.change(t + d, uid, end);
        if end != IDLE {
            self.change(t + d, uid, IDLE);
        }
    }
    /// IDLE → `end` → IDLE at `t` (no RUNNING).
    fn instant(&mut self, t: i64, uid: u16, end: u8) {
        self.change(t, uid, end);
        self.change(t, uid, IDLE);
    }
}

/// The hand-made session: a (A) succeeds after 1, 2, 3 s and is halted
/// after 2 s; a2 (A) succeeds after 2 s; b (B) succeeds after 1 and 3 s and
/// fails after 2 and 6 s (a second apart, from `t0`); c (C) returns
/// SUCCESS, FAILURE, SUCCESS at once; the session ends with a2 running for
/// 0.5 s.
fn hand_made(lg: &mut Logger, t0: i64, uids: [u16; 4]) {
    let [a, c, a2, b] = uids;
    let mut t = t0;
    for (uid, d, end) in [
        (a, S, OK),
        (a, 2 * S, OK),
        (a, 3 * S, OK),
        (a, 2 * S, IDLE),
        (a2, 2 * S, OK),
        (b, S, OK),
        (b, 2 * S, FAIL),
        (b, 3 * S, OK),
        (b, 6 * S, FAIL),
    ] {
        lg.episode(t, uid, d, end);
        t += d + S;
    }
    for end in [OK, FAIL, OK] {
        lg.instant(t, c, end);
        t += S;
    }
    lg.change(t, a2, RUN);
    lg.change(t + S / 2, c, OK);
}

fn mu_nu(t: &Timing) -> (Option<f64>, Option<f64>) {
    match t {
        Timing::Exponential { mu, nu, .. } => (mu.map(|m| m.value), nu.map(|n| n.value)),
        t => panic!("not exponential: {t:?}"),
    }
}

#[test]
fn hand_made_database_fits_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("run.db3");
    let mut lg = Logger::create(&p);
    lg.session(XML, &[1, 2, 3, 4, 5]);
    hand_made(&mut lg, T0, [2, 3, 4, 5]);
    drop(lg);

    let logs = read_logs(&p).unwrap();
    assert_eq!(logs.len(), 1);
    let log = &logs[0];
    assert!(log.file.ends_with("run.db3 (session 1)"), "{}", log.file);
    assert_eq!(log.xml.as_deref(), Some(XML));
    // 9 episodes × 3 rows - 1 (the halt has no IDLE after it), 3 × 2 instant
    // rows, and the last 2 rows
    assert_eq!(log.records, 9 * 3 - 1 + 6 + 2);
    let a = &log.leaves[0];
    let ends: Vec<(f64, End)> = a.episodes.iter().map(|e| (e.duration, e.end)).collect();
    assert_eq!(
        ends,
        [
            (1.0, End::Success),
            (2.0, End::Success),
            (3.0, End::Success),
            (2.0, End::Halted)
        ]
    );
    // a2: the success, then censored at the session's last row, 0.5 s later
    let a2: Vec<(f64, End)> = log.leaves[2]
        .episodes
        .iter()
        .map(|e| (e.duration, e.end))
        .collect();
    assert_eq!(a2, [(2.0, End::Success), (0.5, End::Halted)]);

    let f = fit_logs(&logs, By::Id).unwrap();
    let keys: Vec<&str> = f.leaves.iter().map(|l| l.key.as_str()).collect();
    assert_eq!(keys, ["A", "C", "B"]);
    // A: successes 1 + 2 + 3 + 2 = 8 s, halts 2 + 0.5 s, no failure:
    // ps = 1, mu = 4 / 10.5
    let a = &f.leaves[0];
    assert_eq!(a.ps.value, 1.0);
    assert_eq!(
        (a.counts.successes, a.counts.failures, a.counts.halted),
        (4, 0, 2)
    );
    let (mu, nu) = mu_nu(&a.timing);
    assert!((mu.unwrap() - 4.0 / 10.5).abs() < 1e-12 && nu.is_none());
    // C: a condition, 3 successes of 4 (the last one included)
    assert_eq!(f.leaves[1].timing, Timing::Condition);
    assert_eq!(f.leaves[1].ps.value, 0.75);
    // B: 2 of 4 succeed; mu = 2 / (1 + 3), nu = 2 / (2 + 6)
    let b = &f.leaves[2];
    assert_eq!(b.ps.value, 0.5);
    let (mu, nu) = mu_nu(&b.timing);
    assert!((mu.unwrap() - 0.5).abs() < 1e-12 && (nu.unwrap() - 0.25).abs() < 1e-12);

    // by name: a alone: 3 successes over 6 + 2 s
    let f = fit_logs(&logs, By::Name).unwrap();
    let a = f.leaves.iter().find(|l| l.key == "a").unwrap();
    assert!((mu_nu(&a.timing).0.unwrap() - 3.0 / 8.0).abs() < 1e-12);
}

#[test]
fn sessions_are_runs_each_with_its_tree() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("runs.btdb");
    let mut lg = Logger::create(&p);
    lg.session(XML, &[1, 2, 3, 4, 5]);
    hand_made(&mut lg, T0, [2, 3, 4, 5]);
    lg.session(XML2, &[10, 11, 12, 13, 14]);
    // a, c, a2, b have uids 14, 13, 12, 11 in the second tree
    hand_made(&mut lg, T0 + 1000 * S, [14, 13, 12, 11]);
    drop(lg);
    let logs = read_logs(&p).unwrap();
    let files: Vec<String> = logs
        .iter()
        .map(|l| l.file.rsplit('/').next().unwrap().to_string())
        .collect();
    assert_eq!(files, ["runs.btdb (session 1)", "runs.btdb (session 2)"]);
    assert_eq!(logs[1].xml.as_deref(), Some(XML2));
    // the same episodes twice: the same rates, twice the counts
    let f = fit_logs(&logs, By::Id).unwrap();
    let a = &f.leaves[0];
    assert_eq!((a.counts.successes, a.counts.halted), (8, 4));
    assert!((mu_nu(&a.timing).0.unwrap() - 8.0 / 21.0).abs() < 1e-12);
    let b = &f.leaves[2];
    assert_eq!((b.counts.successes, b.counts.failures), (4, 4));
    let (mu, nu) = mu_nu(&b.timing);
    assert!((mu.unwrap() - 0.5).abs() < 1e-12 && (nu.unwrap() - 0.25).abs() < 1e-12);
}

/// splitmix64: reproducible uniforms in (0, 1).
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
}

/// Episodes of known parameters, on a 1/64 s grid (exact in binary and in
/// µs, so CSV seconds and SQLite µs give the same doubles): per run, A with
/// ps 0.7, mu 0.5, nu 0.2, one in ten halted at a uniform fraction of its
/// duration, and C returning SUCCESS with probability 0.8 at once.
/// Rows: (run, uid of a, uid of c, start ticks, end ticks, end state).
fn generated(runs: usize, per_run: usize) -> Vec<Vec<(bool, i64, i64, u8)>> {
    let mut rng = Rng(42);
    let mut out = Vec::new();
    let mut t = 64; // ticks of 1/64 s, on from run to run
    for _ in 0..runs {
        let mut eps = Vec::new();
        for _ in 0..per_run {
            let ok = rng.uniform() < 0.7;
            let rate = if ok { 0.5 } else { 0.2 };
            let d = -rng.uniform().ln() / rate;
            let (d, end) = if rng.uniform() < 0.1 {
                (d * rng.uniform(), IDLE)
            } else {
                (d, if ok { OK } else { FAIL })
            };
            let d = ((d * 64.0).round() as i64).max(1);
            eps.push((true, t, t + d, end));
            t += d + 64;
            let c = if rng.uniform() < 0.8 { OK } else { FAIL };
            eps.push((false, t, t, c));
            t += 64;
        }
        out.push(eps);
    }
    out
}

fn secs(ticks: i64) -> String {
    format!("{}", ticks as f64 / 64.0)
}

fn fit_file(path: &Path) -> String {
    let out = bin().arg("fit").arg(path).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    // the header names the files; the parameters follow
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| format!("{l}\n"))
        .collect()
}

#[test]
fn csv_and_sqlite_of_the_same_episodes_give_the_same_params() {
    let runs = generated(3, 80);
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("run,node,start,end,status\n");
    for (r, eps) in runs.iter().enumerate() {
        for &(is_a, s, e, end) in eps {
            let status = match end {
                OK => "success",
                FAIL => "failure",
                _ => "halted",
            };
            let node = if is_a { "A" } else { "C" };
            csv.push_str(&format!(
                "{},{node},{},{},{status}\n",
                r + 1,
                secs(s),
                secs(e)
            ));
        }
    }
    let csv_path = dir.path().join("episodes.csv");
    std::fs::write(&csv_path, csv).unwrap();

    let tree = r#"<root BTCPP_format="4">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence _uid="1"><A name="a" _uid="2"/><C name="c" _uid="3"/></Sequence>
  </BehaviorTree>
  <TreeNodesModel><Action ID="A"/><Condition ID="C"/></TreeNodesModel>
</root>"#;
    let write_db = |path: &Path, schema: &str| {
        let mut lg = Logger::with_schema(path, schema);
        for eps in &runs {
            lg.session(tree, &[1, 2, 3]);
            for &(is_a, s, e, end) in eps {
                let us = |ticks: i64| T0 + ticks * 15_625; // 1/64 s = 15625 µs
                if is_a {
                    lg.episode(us(s), 2, us(e) - us(s), end);
                } else {
                    lg.instant(us(s), 3, end);
                }
            }
        }
    };
    // an extension BT.CPP would not accept: detected by the magic bytes
    let db = dir.path().join("episodes.log");
    write_db(&db, SCHEMA);
    // BT.CPP 4.1–4.5 named the uid column `uid`
    let old = dir.path().join("old.db3");
    write_db(
        &old,
        &SCHEMA
            .replace("node_uid", "uid")
            .replace("extra_data", "metadata"),
    );

    let from_csv = fit_file(&csv_path);
    assert!(from_csv.starts_with("\"A\": {ps: 0.") && from_csv.contains("\"C\""));
    assert_eq!(fit_file(&db), from_csv);
    assert_eq!(fit_file(&old), from_csv);
}

fn fit_err(path: &Path) -> String {
    let out_file = path.with_extension("out.yaml");
    std::fs::write(&out_file, "old").unwrap();
    let before = std::fs::read(path).unwrap();
    let o = bin()
        .arg("fit")
        .arg(path)
        .arg("-o")
        .arg(&out_file)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert_eq!(std::fs::read_to_string(&out_file).unwrap(), "old");
    // opened read-only: the file is untouched
    assert_eq!(std::fs::read(path).unwrap(), before);
    String::from_utf8(o.stderr).unwrap()
}

/// A one-session database of the hand-made episodes, then `sql` run on it.
fn broken(dir: &Path, name: &str, sql: &str) -> PathBuf {
    let p = dir.join(name);
    let mut lg = Logger::create(&p);
    lg.session(XML, &[1, 2, 3, 4, 5]);
    hand_made(&mut lg, T0, [2, 3, 4, 5]);
    lg.db.execute_batch(sql).unwrap();
    p
}

#[test]
fn malformed_databases_give_located_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = T0; // the first row: a goes RUNNING

    // wrong schema: another program's database
    let p = d.join("other.db3");
    Connection::open(&p)
        .unwrap()
        .execute_batch("CREATE TABLE Foo (x INTEGER); INSERT INTO Foo VALUES (1);")
        .unwrap();
    let e = fit_err(&p);
    assert!(
        e.contains("other.db3: the schema")
            && e.contains("no table `Definitions`")
            && e.contains("Foo"),
        "{e}"
    );
    let e = fit_err(&broken(
        d,
        "nostate.db3",
        "ALTER TABLE Transitions RENAME COLUMN state TO status;",
    ));
    assert!(
        e.contains("nostate.db3: table Transitions") && e.contains("no column `state`"),
        "{e}"
    );

    // unknown uid, bad state code, a state that is not a number
    let e = fit_err(&broken(
        d,
        "uid.db3",
        &format!("UPDATE Transitions SET node_uid = 9 WHERE timestamp = {first};"),
    ));
    assert!(
        e.contains(&format!("uid.db3: table Transitions, row {first}"))
            && e.contains("node uid 9 is not in the tree of session 1")
            && e.contains("1..5"),
        "{e}"
    );
    let e = fit_err(&broken(
        d,
        "state.db3",
        &format!(
            "UPDATE Transitions SET state = 7 WHERE timestamp = {};",
            first + S
        ),
    ));
    assert!(
        e.contains(&format!("table Transitions, row {}", first + S)) && e.contains("state 7"),
        "{e}"
    );
    let e = fit_err(&broken(
        d,
        "text.db3",
        &format!("UPDATE Transitions SET state = 'ok' WHERE timestamp = {first};"),
    ));
    assert!(
        e.contains(&format!("row {first}")) && e.contains("state is text"),
        "{e}"
    );
    // RUNNING twice
    let e = fit_err(&broken(
        d,
        "twice.db3",
        &format!(
            "UPDATE Transitions SET state = 1 WHERE timestamp = {};",
            first + S
        ),
    ));
    assert!(
        e.contains(&format!("row {}", first + S)) && e.contains("RUNNING to RUNNING"),
        "{e}"
    );
    // a session with no tree; a tree that is not XML
    let e = fit_err(&broken(
        d,
        "session.db3",
        &format!("UPDATE Transitions SET session_id = 3 WHERE timestamp = {first};"),
    ));
    assert!(
        e.contains(&format!("row {first}")) && e.contains("session_id 3 has no row"),
        "{e}"
    );
    let e = fit_err(&broken(
        d,
        "xml.db3",
        "UPDATE Definitions SET xml_tree = '<root><BehaviorTree>' WHERE session_id = 1;",
    ));
    assert!(
        e.contains("xml.db3: table Definitions, row 1 (session 1), xml_tree"),
        "{e}"
    );

    // truncated: the first half of a database of several pages (SQLite
    // finds it out reading the schema)
    let p = d.join("full.db3");
    let mut lg = Logger::create(&p);
    lg.session(XML, &[1, 2, 3, 4, 5]);
    for i in 0..2000 {
        lg.episode(T0 + i * 3 * S, 2, S, OK);
    }
    drop(lg);
    let bytes = std::fs::read(&p).unwrap();
    assert!(bytes.len() > 8 * 4096, "{}", bytes.len());
    let cut = d.join("cut.db3");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = fit_err(&cut);
    assert!(
        e.contains("cut.db3: the schema") && e.contains("malformed"),
        "{e}"
    );
    // truncated inside the header, or not a database at all
    let short = d.join("short.db3");
    std::fs::write(&short, &bytes[..10]).unwrap();
    let e = fit_err(&short);
    assert!(
        e.contains("short.db3: byte offset 0") && e.contains("not an SQLite database"),
        "{e}"
    );
    let garbage = d.join("garbage.db3");
    std::fs::write(&garbage, b"SQLite format 3\0 and then garbage").unwrap();
    let e = fit_err(&garbage);
    assert!(e.contains("garbage.db3") && e.contains("SQLite"), "{e}");
}
