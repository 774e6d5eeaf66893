//! One right-hand-side evaluation per formulation (automatic
//! differentiation) against the hand-written sleigh equations, at the
//! generic state of `nonholo_bench::setup`; one Jacobian of B and of visc
//! (both forms); one
//! residual of formulation A (and its explicit right-hand side where the
//! embedding crate has one).
//!
//! `cargo bench -p nonholo-bench --bench rhs`; the ratios AD / hand-written
//! as a table: `cargo run --release -p nonholo-bench --bin rhs-report`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nonholo_bench::setup::{RhsCase, embedding_explicit, residual_case, rhs_pairs};

fn bench_rhs(c: &mut Criterion, group: &str, case: &mut RhsCase) {
    let mut dy = vec![0.0; case.dim()];
    if let Err(e) = case.eval(&mut dy) {
        eprintln!(
            "{group}/{}: skipped, the rhs fails: {}",
            case.name, e.message
        );
        return;
    }
    c.bench_function(&format!("{group}/{}", case.name), |b| {
        b.iter(|| {
            let _ = black_box(case.eval(black_box(&mut dy)));
        })
    });
}

fn bench_jacobian(c: &mut Criterion, case: &mut RhsCase) {
    let mut jac = vec![0.0; case.dim() * case.dim()];
    match case.jacobian(&mut jac) {
        Ok(true) => {}
        Ok(false) => return,
        Err(e) => {
            eprintln!("jacobian/{}: skipped: {}", case.name, e.message);
            return;
        }
    }
    c.bench_function(&format!("jacobian/{}", case.name), |b| {
        b.iter(|| {
            let _ = black_box(case.jacobian(black_box(&mut jac)));
        })
    });
}

fn rhs(c: &mut Criterion) {
    let mut pairs = match rhs_pairs() {
        Ok(p) => p,
        Err(e) => {
            eprintln!("cannot set up the formulations: {e}");
            return;
        }
    };
    for (ad, hand) in pairs.iter_mut() {
        bench_rhs(c, "rhs", ad);
        bench_rhs(c, "rhs", hand);
    }
    for (ad, hand) in pairs.iter_mut() {
        if ad.name == "B" || ad.name == "visc" || ad.name == "visc adapted" {
            bench_jacobian(c, ad);
        }
        if hand.name == "B reduced" {
            bench_jacobian(c, hand);
        }
    }
    match residual_case() {
        Ok(mut a) => {
            let mut res = vec![0.0; a.dim()];
            if a.eval(&mut res).is_ok() {
                c.bench_function("rhs/A residual", |b| {
                    b.iter(|| {
                        let _ = black_box(a.eval(black_box(&mut res)));
                    })
                });
            }
        }
        Err(e) => eprintln!("A residual: skipped: {e}"),
    }
    match embedding_explicit(true) {
        Ok(mut a) => bench_rhs(c, "rhs", &mut a),
        Err(e) => eprintln!("A explicit: skipped: {e}"),
    }
}

criterion_group!(benches, rhs);
criterion_main!(benches);
