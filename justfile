# Convenience recipes; every one is a plain cargo command (see README).

default:
    @just --list

# Regenerate every figure that backs a claim (the main job).
reproduce *ARGS:
    cargo run --release --bin nonholo -- reproduce {{ARGS}}

# Run experiments/NAME.toml into results/NAME/.
experiment NAME *ARGS:
    cargo run --release --bin nonholo -- experiment experiments/{{NAME}}.toml {{ARGS}}

# Error against cost: every work-precision experiment (or the files given).
work-precision *FILES:
    cargo run --release --bin nonholo -- work-precision {{FILES}}

# Redraw the figures of experiments/NAME.toml from stored results.
plot NAME:
    cargo run --release --bin nonholo -- plot experiments/{{NAME}}.toml

# Run the test suite (what CI runs).
test:
    cargo test --release --workspace

# Format, lint and test, as CI does.
ci:
    .ci/run

# List the scenes.
scenes:
    cargo run --release --bin nonholo -- scenes

# Solve a boundary-value problem: just bvp --ends-from c.json ...
bvp *ARGS:
    cargo run --release --bin nonholo -- bvp {{ARGS}}

# The cost of a Newton step of the boundary-value solver against the grid (results/bvp-scaling).
bvp-scaling *ARGS:
    cargo run --release -p nonholo-bench --bin bvp-scaling -- {{ARGS}}

# Run one motion: just simulate --scene sleigh-incline ...
simulate *ARGS:
    cargo run --release --bin nonholo -- simulate {{ARGS}}

# Peers side by side (diffsol, ode_solvers): results/peers/peers.csv, docs/peers.md has the numbers.
peers *ARGS:
    cargo run --release -p nonholo-bench --features peers --bin peers -- {{ARGS}}

# Benchmark one right-hand side per formulation against the hand-written sleigh equations.
bench:
    cargo bench -p nonholo-bench --bench rhs
    cargo run --release -p nonholo-bench --bin rhs-report
