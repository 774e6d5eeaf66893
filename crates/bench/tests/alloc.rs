//! The right-hand sides allocate nothing once warm: a counting global
//! allocator, armed per thread (the test harness runs tests in parallel),
//! around repeated evaluations at the generic sleigh state.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use nonholo_bench::setup::{
    RhsCase, contact_cases, embedding_explicit, residual_case, rhs_pairs, train_case,
};

struct Counting;

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
    static BYTES: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    // `try_with`: the thread-locals may be gone while a thread shuts down.
    let _ = ARMED.try_with(|armed| {
        if armed.get() {
            let _ = COUNT.try_with(|c| c.set(c.get() + 1));
            let _ = BYTES.try_with(|b| b.set(b.get() + size));
        }
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// `(allocations, bytes)` made on this thread by `f`.
fn count<F: FnMut()>(mut f: F) -> (usize, usize) {
    COUNT.with(|c| c.set(0));
    BYTES.with(|b| b.set(0));
    ARMED.with(|a| a.set(true));
    f();
    ARMED.with(|a| a.set(false));
    (COUNT.with(Cell::get), BYTES.with(Cell::get))
}

const REPEATS: usize = 100;

fn assert_rhs_allocates_nothing(case: &mut RhsCase) {
    let mut dy = vec![0.0; case.dim()];
    case.eval(&mut dy).unwrap();
    let mut failed = None;
    let (n, bytes) = count(|| {
        for _ in 0..REPEATS {
            if let Err(e) = case.eval(&mut dy) {
                failed = Some(e);
            }
        }
    });
    assert!(failed.is_none(), "{}: {:?}", case.name, failed);
    assert_eq!(
        n, 0,
        "{} rhs: {n} allocations ({bytes} bytes) in {REPEATS} calls after warm-up",
        case.name
    );
}

#[test]
fn counting_allocator_counts() {
    let (n, bytes) = count(|| {
        let v: Vec<f64> = std::hint::black_box(vec![1.0; 10]);
        drop(v);
    });
    assert_eq!((n, bytes), (1, 80));
}

#[test]
fn rhs_of_b_c_visc_and_mass_allocate_nothing() {
    // Every pair of `rhs_pairs`, `visc`'s adapted form and its body-frame
    // baseline included.
    for (mut ad, mut hand) in rhs_pairs().unwrap() {
        assert_rhs_allocates_nothing(&mut ad);
        assert_rhs_allocates_nothing(&mut hand);
    }
}

#[test]
fn jacobian_of_b_allocates_nothing() {
    let mut pairs = rhs_pairs().unwrap();
    let (b, _) = pairs.iter_mut().find(|(ad, _)| ad.name == "B").unwrap();
    let mut jac = vec![0.0; b.dim() * b.dim()];
    assert!(b.jacobian(&mut jac).unwrap());
    let (n, bytes) = count(|| {
        for _ in 0..REPEATS {
            b.jacobian(&mut jac).unwrap();
        }
    });
    assert_eq!(
        n, 0,
        "B jacobian: {n} allocations ({bytes} bytes) in {REPEATS} calls"
    );
}

#[test]
fn residual_of_a_allocates_nothing() {
    let mut a = residual_case().unwrap();
    let mut res = vec![0.0; a.dim()];
    a.eval(&mut res).unwrap();
    let (n, bytes) = count(|| {
        for _ in 0..REPEATS {
            a.eval(&mut res).unwrap();
        }
    });
    assert_eq!(
        n, 0,
        "A residual: {n} allocations ({bytes} bytes) in {REPEATS} calls"
    );
}

#[test]
fn explicit_rhs_of_a_allocates_nothing() {
    assert_rhs_allocates_nothing(&mut embedding_explicit(true).unwrap());
    assert_rhs_allocates_nothing(&mut embedding_explicit(false).unwrap());
}

/// Every AD Jacobian (B again, C, visc in both forms — the adapted one by
/// nested dual numbers —, both forms of mass).
#[test]
fn every_ad_jacobian_allocates_nothing() {
    for (mut ad, _) in rhs_pairs().unwrap() {
        let dim = ad.dim();
        let mut jac = vec![0.0; dim * dim];
        if !ad.jacobian(&mut jac).unwrap() {
            eprintln!("{}: no Jacobian", ad.name);
            continue;
        }
        let (n, bytes) = count(|| {
            for _ in 0..REPEATS {
                ad.jacobian(&mut jac).unwrap();
            }
        });
        assert_eq!(
            n, 0,
            "{} jacobian: {n} allocations ({bytes} bytes) in {REPEATS} calls",
            ad.name
        );
    }
}

/// The contact crate's right-hand sides and Jacobians allocate nothing:
/// friction sticking and slipping (the friction cone is solved only at
/// transitions), and gauss, whose Clarabel program is updated in place.
#[test]
fn gauss_and_friction_allocate_nothing() {
    for mut case in contact_cases().unwrap() {
        assert_rhs_allocates_nothing(&mut case);
        let dim = case.dim();
        let mut jac = vec![0.0; dim * dim];
        assert!(case.jacobian(&mut jac).unwrap());
        let (n, bytes) = count(|| {
            for _ in 0..REPEATS {
                case.jacobian(&mut jac).unwrap();
            }
        });
        assert_eq!(
            n, 0,
            "{} jacobian: {n} allocations ({bytes} bytes)",
            case.name
        );
    }
}

/// B on twenty hitched sleighs solves its 118-row KKT system sparse with
/// faer (real for the right-hand side, `Dual64` for Jacobian columns):
/// once warm, neither allocates (faer's numeric LU keeps its factor storage
/// and the `MemBuffer` between solves).
#[test]
fn sparse_rhs_and_jacobian_of_the_train_allocate_nothing() {
    let mut b = train_case(20).unwrap();
    // 60 coordinates, 20 blades, 38 hitch rows: the sparse path.
    assert_eq!(b.dim(), 120);
    const { assert!(118 >= nonholo_core::sparse::SPARSE_FROM) };
    assert_rhs_allocates_nothing(&mut b);
    let dim = b.dim();
    let mut jac = vec![0.0; dim * dim];
    assert!(b.jacobian(&mut jac).unwrap());
    let (n, bytes) = count(|| {
        for _ in 0..10 {
            b.jacobian(&mut jac).unwrap();
        }
    });
    assert_eq!(
        n, 0,
        "train jacobian: {n} allocations ({bytes} bytes) in 10 calls"
    );
}
