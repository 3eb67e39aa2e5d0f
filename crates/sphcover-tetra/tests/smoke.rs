mod common;
use sphcover_tetra::{RegularTriangulation, TriangulationParams};

#[test]
fn smoke_random() {
    for (n, wmax) in [(10, 0.0), (50, 0.0), (200, 0.01), (500, 0.003)] {
        let (p, w) = common::random_points(n, wmax, n as u64);
        let t = RegularTriangulation::new(&p, &w, &TriangulationParams::default()).unwrap();
        println!("{:?}", t.stats());
        t.check_validity().unwrap();
    }
}

#[test]
fn smoke_grid() {
    let (p, w) = common::grid(5, 1.0, 0.3);
    let t = RegularTriangulation::new(&p, &w, &TriangulationParams::default()).unwrap();
    println!("{:?}", t.stats());
    t.check_validity().unwrap();
}
