//! The SPRT's statistics: simulated objects of known visible fraction s,
//! thousands of runs each. For s well above s_thresh the test should
//! rarely say "invisible", for s well below it rarely "visible", within
//! what A and B promise: at a stop above A the posterior odds of the wrong
//! answer are under 1/A, below B under B (so error rates of 1/(1+A) and
//! B/(1+B) at most, and far less away from the threshold).

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use vis5d::sprt::{Decision, Sprt, SprtParams};

/// Runs the test `runs` times on Bernoulli(s) rays: (fraction decided
/// visible, fraction decided invisible, mean rays).
fn simulate(params: SprtParams, s: f64, runs: u32, seed: u64) -> (f64, f64, f64) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut vis, mut inv, mut rays) = (0u32, 0u32, 0u64);
    for _ in 0..runs {
        let mut t = Sprt::new(params);
        loop {
            match t.push(rng.random::<f64>() < s) {
                Decision::Undecided => continue,
                Decision::Invisible => inv += 1,
                Decision::Visible | Decision::CapReached => vis += 1,
            }
            break;
        }
        rays += t.rays() as u64;
    }
    (
        vis as f64 / runs as f64,
        inv as f64 / runs as f64,
        rays as f64 / runs as f64,
    )
}

#[test]
fn wrong_decisions_stay_within_what_a_and_b_promise() {
    let paper = SprtParams {
        max_rays: 100_000,
        ..SprtParams::PAPER_EXAMPLE
    };
    check(paper);
    check(vis5d::builder::BuildParams::default().sprt);
}

fn check(params: SprtParams) {
    let st = params.s_thresh;
    let bound_inv = params.reject / (1.0 + params.reject); // wrong "invisible"
    let bound_vis = 1.0 / (1.0 + params.accept); // wrong "visible"
    println!(
        "s       visible  invisible  mean rays   (s_thresh {st}, A {}, B {}, prior Beta({}, {}), cap {})",
        params.accept, params.reject, params.prior_a, params.prior_b, params.max_rays
    );
    for (k, s) in [0.1, 0.05, 0.03, 0.003, 0.001, 0.0].into_iter().enumerate() {
        let (vis, inv, mean) = simulate(params, s, 4000, k as u64);
        println!("{s:<7} {vis:<8.4} {inv:<10.4} {mean:.1}");
        if s >= 3.0 * st {
            assert!(
                inv <= bound_inv,
                "s = {s}: wrongly invisible {inv} > {bound_inv}"
            );
        }
        if s <= st / 3.0 {
            assert!(
                vis <= bound_vis,
                "s = {s}: wrongly visible {vis} > {bound_vis}"
            );
        }
    }
}
