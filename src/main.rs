//! The `btrel` command: a thin front over the library.

mod cli;

// Parsing and analysing million-node trees allocates millions of small
// objects, on the parser's own thread: mimalloc roughly halves that time
// compared with the system allocator.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    cli::main()
}
