//! Writes a random Sequence/Fallback tree:
//! `cargo run --release --example gen_tree -- LEAVES SEED [mixed] > tree.yaml`
//! (`mixed`: a third each of deterministic, hybrid and exponential actions).
fn main() {
    let mut args = std::env::args().skip(1);
    let leaves = args.next().and_then(|s| s.parse().ok()).unwrap_or(1000);
    let seed = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    let shape = match args.next().as_deref() {
        Some("mixed") => btrel::generate::Shape::mixed_timing(leaves),
        _ => btrel::generate::Shape::sequence_fallback(leaves),
    };
    print!("{}", btrel::generate::random_tree_yaml(&shape, seed));
}
