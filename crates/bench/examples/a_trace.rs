use nonholo_embedding::ode::Reduction;
use nonholo_embedding::traced::TracedArray;
use std::time::Instant;

fn main() {
    let case = nonholo_bench::setup::residual_case().unwrap();
    let ex = case.sys.into_explicit();
    let scene = &*ex.shared.scene;
    let e = &ex.shared.e;
    let m = ex.shared.m;
    let y = case.y.clone();
    let t0 = 0.0;
    let mut r: Reduction = Reduction::new(m);
    r.fourth(scene, e, t0, &y[..4 * m]).unwrap();
    let d0: Vec<f64> = r.state().to_vec();
    let s = Instant::now();
    let a = TracedArray::new(scene, e, t0, &d0, &[]).unwrap();
    println!("trace+diff {:?}, sizes {:?}", s.elapsed(), a.sizes());
    let mut w = a.workspace();
    let s = Instant::now();
    a.solve(&mut w, t0, &d0);
    a.value(&mut w, t0, &d0);
    a.project(&mut w, t0, &d0);
    println!("first runs (compile) {:?}", s.elapsed());
    let n = 20000;
    for rep in 0..3 {
        let s = Instant::now();
        for _ in 0..n {
            std::hint::black_box(a.value(&mut w, std::hint::black_box(t0), &d0));
        }
        let tv = s.elapsed().as_nanos() as f64 / n as f64;
        let s = Instant::now();
        for _ in 0..n {
            std::hint::black_box(a.solve(&mut w, std::hint::black_box(t0), &d0));
        }
        let ts = s.elapsed().as_nanos() as f64 / n as f64;
        let s = Instant::now();
        for i in 0..n {
            let t = if i % 2 == 0 {
                t0
            } else {
                f64::from_bits(t0.to_bits() + 1)
            };
            std::hint::black_box(r.fourth(scene, e, t, &y[..4 * m]).unwrap());
        }
        let tf = s.elapsed().as_nanos() as f64 / n as f64;
        println!(
            "rep {rep}: value {tv:.0} ns, solve program {ts:.0} ns, fourth {tf:.0} ns, stats {:?}",
            r.stats()
        );
    }
}
