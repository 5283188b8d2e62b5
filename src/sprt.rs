//! The beta-function sequential probability ratio test of papers/003
//! sec. 5 (Gotsman, Sudarsky & Fayman 1999), deciding from rays, one at a
//! time, whether an object is visible from a view cell.
//!
//! Let s be the fraction of the (cell point, object surface point) rays
//! that reach the object unoccluded. With a prior Beta(a, b) on s, after r
//! rays of which h hit, s follows Beta(h + a, r - h + b), and the
//! posterior odds that s exceeds the threshold s_thresh are
//!
//! ```text
//! odds = P(s > s_thresh) / P(s <= s_thresh)
//!      = I_{1 - s_thresh}(r - h + b, h + a) / I_{s_thresh}(h + a, r - h + b)
//! ```
//!
//! (I is the regularised incomplete beta function; the upper tail is taken
//! as I_{1-x}(b, a), not 1 - I_x(a, b), for accuracy). The test samples
//! while `B <= odds <= A`; above A the object is visible, below B
//! invisible; reaching the ray cap ends undecided, which counts as visible.
//!
//! Note: deviations from the paper (DESIGN.md, "SPRT"):
//! - the prior is a parameter; the paper assumes the uniform Beta(1, 1),
//!   under which its own worked example does not hold (the prior odds are
//!   already 99 > A = 50). The example holds with Beta(1, k), 48 <= k <= 91;
//! - at least one ray is needed before any decision.

/// The parameters of the test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SprtParams {
    /// The visible fraction that separates "visible" from "invisible".
    pub s_thresh: f64,
    /// Odds above which the object is declared visible (the paper's A).
    pub accept: f64,
    /// Odds below which the object is declared invisible (the paper's B).
    pub reject: f64,
    /// The prior's first shape parameter a (pseudo-hits).
    pub prior_a: f64,
    /// The prior's second shape parameter b (pseudo-misses).
    pub prior_b: f64,
    /// Rays after which the test stops undecided (counted as visible).
    pub max_rays: u32,
}

/// The largest ray cap of a test that builds accept: each undecided object
/// of each cell may cost that many rays.
pub const MAX_RAY_CAP: u32 = 1_000_000;

/// Parameters of the test outside their domain.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum SprtError {
    /// `s_thresh` is not a fraction strictly between 0 and 1.
    #[error("the SPRT's s_thresh must be in (0, 1), not {0}")]
    Threshold(f64),
    /// The odds bounds are not `0 < B < A < inf`.
    #[error(
        "the SPRT's odds bounds must satisfy 0 < B < A < inf (B rejects, A accepts), \
         not B = {reject} and A = {accept}"
    )]
    OddsBounds {
        /// B.
        reject: f64,
        /// A.
        accept: f64,
    },
    /// The prior's shape parameters are not positive and finite.
    #[error("the SPRT's prior Beta(a, b) needs finite a, b > 0, not ({a}, {b})")]
    Prior {
        /// a.
        a: f64,
        /// b.
        b: f64,
    },
    /// The ray cap is 0 or above [`MAX_RAY_CAP`].
    #[error("the SPRT's ray cap must be in 1..={MAX_RAY_CAP}, not {0}")]
    RayCap(u32),
}

impl SprtParams {
    /// The paper's worked example: s_thresh 0.01, A 50, B 0.2, with the
    /// Beta(1, 50) prior under which the example holds, no practical cap.
    pub const PAPER_EXAMPLE: SprtParams = SprtParams {
        s_thresh: 0.01,
        accept: 50.0,
        reject: 0.2,
        prior_a: 1.0,
        prior_b: 50.0,
        max_rays: MAX_RAY_CAP,
    };

    /// Checks that every parameter is in its domain; the error says which
    /// is not.
    pub fn validate(&self) -> Result<(), SprtError> {
        if !(self.s_thresh > 0.0 && self.s_thresh < 1.0) {
            return Err(SprtError::Threshold(self.s_thresh));
        }
        if !(self.reject > 0.0 && self.reject < self.accept && self.accept.is_finite()) {
            return Err(SprtError::OddsBounds {
                reject: self.reject,
                accept: self.accept,
            });
        }
        let positive = |x: f64| x > 0.0 && x.is_finite();
        if !(positive(self.prior_a) && positive(self.prior_b)) {
            return Err(SprtError::Prior {
                a: self.prior_a,
                b: self.prior_b,
            });
        }
        if !(1..=MAX_RAY_CAP).contains(&self.max_rays) {
            return Err(SprtError::RayCap(self.max_rays));
        }
        Ok(())
    }

    /// The number of misses in a row after which the test stops: with
    /// `prior_a = 1` and A above the odds after one miss, it says
    /// invisible at the smallest r with
    /// `(1 - s_thresh)^(r + prior_b) < B / (1 + B)`.
    pub fn misses_to_invisible(&self) -> u32 {
        self.misses_decision().0
    }

    /// What the test decides on a run of misses, and after how many: the
    /// whole story for an object no ray has hit, computed once by running
    /// the test (the builder then counts misses instead of evaluating the
    /// incomplete beta function per ray).
    pub fn misses_decision(&self) -> (u32, Decision) {
        let mut t = Sprt::new(*self);
        loop {
            match t.push(false) {
                Decision::Undecided => {}
                d => return (t.rays(), d),
            }
        }
    }

    /// Whether misses alone can only lead to "invisible" (or the cap):
    /// false when the odds after one miss are still above A, so the test
    /// would call an object visible without ever seeing it hit.
    pub fn misses_mean_invisible(&self) -> bool {
        let mut t = Sprt::new(*self);
        t.push(false) != Decision::Visible
    }
}

/// What the test says after a ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Decision {
    /// Keep sampling.
    Undecided,
    /// The odds rose above A.
    Visible,
    /// The odds fell below B.
    Invisible,
    /// The ray cap was reached undecided: counted as visible.
    CapReached,
}

impl Decision {
    /// Whether the object goes into the visible set.
    pub fn is_visible(self) -> bool {
        matches!(self, Decision::Visible | Decision::CapReached)
    }
}

/// The state of one test: rays and hits so far.
#[derive(Clone, Copy, Debug)]
pub struct Sprt {
    params: SprtParams,
    rays: u32,
    hits: u32,
}

impl Sprt {
    /// A test with no ray yet.
    pub fn new(params: SprtParams) -> Self {
        Self {
            params,
            rays: 0,
            hits: 0,
        }
    }

    /// Rays taken so far.
    pub fn rays(&self) -> u32 {
        self.rays
    }

    /// Hits among them.
    pub fn hits(&self) -> u32 {
        self.hits
    }

    /// The posterior odds that s exceeds s_thresh (infinite when all the
    /// posterior mass is above it).
    pub fn odds(&self) -> f64 {
        let p = &self.params;
        let a = self.hits as f64 + p.prior_a;
        let b = (self.rays - self.hits) as f64 + p.prior_b;
        let below = statrs::function::beta::beta_reg(a, b, p.s_thresh);
        let above = statrs::function::beta::beta_reg(b, a, 1.0 - p.s_thresh);
        if below == 0.0 {
            f64::INFINITY
        } else {
            above / below
        }
    }

    /// Takes one ray (`hit`: whether it reached the object) and decides.
    pub fn push(&mut self, hit: bool) -> Decision {
        self.rays += 1;
        self.hits += hit as u32;
        let odds = self.odds();
        if odds > self.params.accept {
            Decision::Visible
        } else if odds < self.params.reject {
            Decision::Invisible
        } else if self.rays >= self.params.max_rays {
            Decision::CapReached
        } else {
            Decision::Undecided
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(params: SprtParams, seq: &str) -> Vec<Decision> {
        let mut t = Sprt::new(params);
        seq.bytes().map(|c| t.push(c == b'1')).collect()
    }

    #[test]
    fn paper_example_with_beta_1_50_prior_stops_visible_at_11() {
        let d = run(SprtParams::PAPER_EXAMPLE, "00001000011");
        assert!(d[..10].iter().all(|&x| x == Decision::Undecided), "{d:?}");
        assert_eq!(d[10], Decision::Visible);
    }

    #[test]
    fn paper_example_holds_for_prior_b_48_to_91_only() {
        for k in 40..=100 {
            let p = SprtParams {
                prior_b: k as f64,
                ..SprtParams::PAPER_EXAMPLE
            };
            let d = run(p, "00001000011");
            let holds =
                d[..10].iter().all(|&x| x == Decision::Undecided) && d[10] == Decision::Visible;
            assert_eq!(holds, (48..=91).contains(&k), "Beta(1, {k}): {d:?}");
        }
    }

    #[test]
    fn uniform_prior_decides_visible_after_5() {
        let uniform = SprtParams {
            prior_b: 1.0,
            ..SprtParams::PAPER_EXAMPLE
        };
        // The prior odds are 99 > A, but one ray is needed first.
        assert!((Sprt::new(uniform).odds() - 99.0).abs() < 1e-9);
        let d = run(uniform, "00001000011");
        assert!(d[..4].iter().all(|&x| x == Decision::Undecided), "{d:?}");
        assert_eq!(d[4], Decision::Visible);
        let mut t = Sprt::new(uniform);
        for c in "00001".bytes() {
            t.push(c == b'1');
        }
        assert!((t.odds() - 684.0).abs() < 1.0, "{}", t.odds());
    }

    #[test]
    fn misses_only_match_the_closed_form() {
        for s in [0.01, 0.003, 0.05] {
            // A above the prior odds (99 for 0.01, 332 for 0.003), so
            // that misses alone never say "visible".
            let p = SprtParams {
                s_thresh: s,
                prior_b: 1.0,
                accept: 1e6,
                ..SprtParams::PAPER_EXAMPLE
            };
            // The smallest r with (1 - s)^(r + 1) < B / (1 + B).
            let bound = p.reject / (1.0 + p.reject);
            let r = (1u32..)
                .find(|&r| (1.0 - s).powi(r as i32 + 1) < bound)
                .unwrap();
            let d = run(p, &"0".repeat(r as usize));
            assert!(
                d[..r as usize - 1]
                    .iter()
                    .all(|&x| x == Decision::Undecided),
                "s = {s}"
            );
            assert_eq!(d[r as usize - 1], Decision::Invisible, "s = {s}");
            assert_eq!(p.misses_to_invisible(), r);
        }
        // s_thresh 0.01, B 0.2: 178 misses.
        let p = SprtParams {
            prior_b: 1.0,
            ..SprtParams::PAPER_EXAMPLE
        };
        assert_eq!(p.misses_to_invisible(), 178);
    }

    #[test]
    fn the_cap_ends_undecided_as_visible() {
        let p = SprtParams {
            max_rays: 3,
            ..SprtParams::PAPER_EXAMPLE
        };
        let d = run(p, "000");
        assert_eq!(
            d,
            [
                Decision::Undecided,
                Decision::Undecided,
                Decision::CapReached
            ]
        );
        assert!(d[2].is_visible());
    }

    #[test]
    fn bad_parameters_are_refused() {
        let ok = SprtParams::PAPER_EXAMPLE;
        assert!(ok.validate().is_ok());
        for bad in [
            SprtParams {
                s_thresh: 0.0,
                ..ok
            },
            SprtParams {
                s_thresh: 1.0,
                ..ok
            },
            SprtParams { reject: 60.0, ..ok },
            SprtParams { prior_a: 0.0, ..ok },
            SprtParams {
                prior_b: f64::NAN,
                ..ok
            },
            SprtParams { max_rays: 0, ..ok },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
