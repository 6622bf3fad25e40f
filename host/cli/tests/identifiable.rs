//! The numerically found identifiable ε set (docs/model.md §1): the paper's
//! Table II for the AUBO i5, 6n − 2N_r − 3 = 21 for a UR5-style arm, checked
//! against an independent SVD of the same identification Jacobian.

use nalgebra::DMatrix;
use robimu_model::error_selection::{
    candidate_errors, identifiable_errors, identification_matrix, IdentifiableError,
    IdentifiableOptions, IdentifiableSet, IdentificationMatrix,
};
use robimu_model::robot::default_estimated_errors;
use robimu_model::{ErrorIndex, Robot};

fn ur5() -> Robot {
    Robot::from_toml_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/ur5.toml"
    ))
    .unwrap()
}

/// Singular values (descending) of the columns `cols` of the matrix.
fn singular_values(m: &IdentificationMatrix, cols: &[usize]) -> Vec<f64> {
    let a = DMatrix::from_fn(m.rows, cols.len(), |r, c| m.col(cols[c])[r]);
    let mut s: Vec<f64> = a.singular_values().iter().copied().collect();
    s.sort_by(|x, y| y.total_cmp(x));
    s
}

fn column_of(m: &IdentificationMatrix, e: ErrorIndex) -> usize {
    let name = format!("eps_{}_{}", e.link, e.k);
    m.names.iter().position(|n| *n == name).unwrap()
}

/// Independent check by SVD: the 27 + chosen columns are full rank with a
/// clear margin, and appending any dropped candidate adds no rank.
fn check_by_svd(robot: &Robot, opts: &IdentifiableOptions, set: &IdentifiableSet) {
    let m = identification_matrix(robot, opts).unwrap();
    let nb = m.names.len() - m.candidates.len();
    assert_eq!(nb, 27);
    let mut cols: Vec<usize> = (0..nb).collect();
    cols.extend(set.errors.iter().map(|&e| column_of(&m, e)));
    let s = singular_values(&m, &cols);
    let full = s[s.len() - 1] / s[0];
    println!("{}: chosen set σ_min/σ_max = {full:e}", robot.name());
    // A dropped candidate's residual against that span (nalgebra's
    // Householder QR), relative to σ_max; appending it gives a zero σ_min.
    let a = DMatrix::from_fn(m.rows, cols.len(), |r, c| m.col(cols[c])[r]);
    let q = a.qr().q();
    let mut worst: f64 = 0.0;
    for &(e, _) in &set.dropped {
        let c = nalgebra::DVector::from_column_slice(m.col(column_of(&m, e)));
        let res = (&c - &q * (q.transpose() * &c)).norm() / s[0];
        let mut with = cols.clone();
        with.push(column_of(&m, e));
        let sw = singular_values(&m, &with);
        let extra = sw[sw.len() - 1] / sw[0];
        assert!(
            res < 1e-12 && extra < 1e-12,
            "eps_{}_{} adds rank: residual {res:e}, σ_min/σ_max {extra:e}",
            e.link,
            e.k
        );
        worst = worst.max(res);
    }
    println!(
        "{}: dropped candidates' residual against the chosen span ≤ {worst:e} (of σ_max)",
        robot.name()
    );
    assert!(
        full > 1e4 * worst,
        "chosen set not clearly full rank: {full:e} vs {worst:e}"
    );
    // All candidates together: exactly 27 + rank singular values above the gap.
    let all: Vec<usize> = (0..m.names.len()).collect();
    let s = singular_values(&m, &all);
    let r = nb + set.rank;
    let gap = s[r - 1] / s[r];
    println!("{}: all candidates, σ_48/σ_49 = {gap:e}", robot.name());
    assert!(gap > 1e4, "no clear singular value gap at {r}: {gap:e}");
}

fn check_set(robot: &Robot, set: &IdentifiableSet, opts: &IdentifiableOptions) {
    println!(
        "{}: rank {}, pivot gap {:e}, base min pivot {:e}, chosen min residual {:e}",
        robot.name(),
        set.rank,
        set.gap,
        set.base_min_pivot,
        set.chosen_min_residual
    );
    let names: Vec<String> = set
        .errors
        .iter()
        .map(|e| format!("eps_{}_{}", e.link, e.k))
        .collect();
    println!("  chosen: {}", names.join(" "));
    for (e, p) in &set.pivots {
        println!("  pivot eps_{}_{}: {p:e}", e.link, e.k);
    }
    assert_eq!(set.errors.len(), set.rank);
    assert!(set.gap >= 1e4, "pivot gap {:e}", set.gap);
    // Every candidate is either chosen or dropped, exactly once.
    let mut all: Vec<ErrorIndex> = set.errors.clone();
    all.extend(set.dropped.iter().map(|d| d.0));
    all.sort();
    assert_eq!(all, candidate_errors(robot.dof()));
    // Dropped candidates lie in the span; chosen ones are far from it.
    let worst = set.dropped.iter().map(|d| d.1).fold(0.0, f64::max);
    assert!(worst < opts.tolerance, "dropped residual {worst:e}");
    assert!(
        set.chosen_min_residual > 1e4 * worst.max(1e-300).max(1e-16),
        "chosen {:e} vs dropped {worst:e}",
        set.chosen_min_residual
    );
    // The set is a valid estimated set for the robot.
    let r = robot.with_estimated_errors(set.errors.clone()).unwrap();
    assert_eq!(r.estimated_errors(), &set.errors[..]);
}

#[test]
fn aubo_i5_gives_the_papers_table_ii_set() {
    let robot = Robot::aubo_i5();
    let opts = IdentifiableOptions::default();
    let t = std::time::Instant::now();
    let set = identifiable_errors(&robot, &opts).unwrap();
    println!("aubo_i5: identifiable_errors took {:?}", t.elapsed());
    check_set(&robot, &set, &opts);
    assert_eq!(set.rank, 21);
    assert_eq!(set.errors, default_estimated_errors(6));
    check_by_svd(&robot, &opts, &set);
}

#[test]
fn aubo_i5_set_does_not_depend_on_the_seed() {
    let robot = Robot::aubo_i5();
    let opts = IdentifiableOptions {
        seed: 1234,
        duration: 40.0,
        sample_rate: 30.0,
        ..Default::default()
    };
    let set = identifiable_errors(&robot, &opts).unwrap();
    assert_eq!(set.errors, default_estimated_errors(6));
    assert!(set.gap >= 1e4, "pivot gap {:e}", set.gap);
}

#[test]
fn ur5_gives_6n_minus_2nr_minus_3_errors() {
    let robot = ur5();
    let opts = IdentifiableOptions::default();
    let set = identifiable_errors(&robot, &opts).unwrap();
    check_set(&robot, &set, &opts);
    let (n, n_r) = (6, 6);
    assert_eq!(set.rank, 6 * n - 2 * n_r - 3);
    check_by_svd(&robot, &opts, &set);
}

#[test]
fn bad_options_are_typed_errors() {
    let robot = Robot::aubo_i5();
    for (opts, field) in [
        (
            IdentifiableOptions {
                sample_rate: -1.0,
                ..Default::default()
            },
            "sample_rate",
        ),
        (
            IdentifiableOptions {
                tolerance: f64::NAN,
                ..Default::default()
            },
            "tolerance",
        ),
        (
            IdentifiableOptions {
                perturbation: -0.5,
                ..Default::default()
            },
            "perturbation",
        ),
    ] {
        match identifiable_errors(&robot, &opts) {
            Err(IdentifiableError::BadOption { field: f, .. }) => assert_eq!(f, field),
            other => panic!("expected BadOption({field}), got {other:?}"),
        }
    }
}
