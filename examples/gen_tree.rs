//! Writes a random Sequence/Fallback tree: `cargo run --release --example gen_tree -- LEAVES SEED > tree.yaml`.
fn main() {
    let mut args = std::env::args().skip(1);
    let leaves = args.next().and_then(|s| s.parse().ok()).unwrap_or(1000);
    let seed = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    print!(
        "{}",
        btrel::generate::random_tree_yaml(&btrel::generate::Shape::sequence_fallback(leaves), seed)
    );
}
