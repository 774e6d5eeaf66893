# Convenience recipes; every one is a plain cargo command (see README).

default:
    @just --list

# Run the test suite (what CI runs).
test:
    cargo test --release --workspace

# Format, lint and test, as CI does.
ci:
    .ci/run

# List the scenes.
scenes:
    cargo run --release --bin nonholo -- scenes

# Run one motion: just simulate --scene sleigh-incline ...
simulate *ARGS:
    cargo run --release --bin nonholo -- simulate {{ARGS}}
