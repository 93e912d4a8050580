//! Times each phase of `report` on a tree file: `cargo run --release --example phase_timing -- FILE`.
use std::time::Instant;

use btrel::report::Exporter;

// as in the `btrel` binary
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let path = std::env::args().nth(1).expect("usage: phase_timing FILE");
    let t0 = Instant::now();
    let src = std::fs::read_to_string(&path).expect("readable file");
    let t1 = Instant::now();
    let tree = btrel::tree::parse_str(&src, &path).expect("valid tree");
    let t2 = Instant::now();
    let analysis = btrel::compile::analyze(&tree, &Default::default()).expect("analysable tree");
    let t3 = Instant::now();
    let report = btrel::report::Report::new(&tree, &analysis);
    let table = btrel::report::table::TableExporter.to_string(&report);
    let t4 = Instant::now();
    eprintln!(
        "read {:?}  parse {:?}  analyze {:?}  table {:?} ({} bytes)",
        t1 - t0,
        t2 - t1,
        t3 - t2,
        t4 - t3,
        table.len()
    );
}
