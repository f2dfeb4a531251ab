//! Roots of functions of one variable, in double precision: the closed
//! form for quadratics and bisection for a bracketed root. Shared by the
//! shapes whose intersections are roots along the ray (quadrics, signed
//! distance grids, implicit surfaces).

/// The real roots of a·s² + b·s + c in increasing order (one where a is 0,
/// a linear equation), computed without cancellation (Press et al.,
/// "Numerical Recipes", section 5.6).
pub(crate) fn quadratic_roots(a: f64, b: f64, c: f64) -> [Option<f64>; 2] {
    if a == 0.0 {
        return [(b != 0.0).then(|| -c / b), None];
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return [None, None];
    }
    let q = -0.5 * (b + disc.sqrt().copysign(b));
    if q == 0.0 {
        return [Some(0.0), None];
    }
    let (r0, r1) = (q / a, c / q);
    [Some(r0.min(r1)), Some(r0.max(r1))]
}

/// A root of `f` in [a, b], whose ends differ in sign (`fa` its value at
/// a), to double precision (the first one where f is monotonic there).
pub(crate) fn bisect(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64, fa: f64) -> f64 {
    let a_negative = fa < 0.0;
    for _ in 0..64 {
        let m = 0.5 * (a + b);
        if m <= a || m >= b {
            break;
        }
        let fm = f(m);
        if fm == 0.0 {
            return m;
        }
        if (fm < 0.0) == a_negative {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratics_and_bisection() {
        assert_eq!(quadratic_roots(1.0, -3.0, 2.0), [Some(1.0), Some(2.0)]);
        assert_eq!(quadratic_roots(-1.0, 3.0, -2.0), [Some(1.0), Some(2.0)]);
        assert_eq!(quadratic_roots(0.0, 2.0, -4.0), [Some(2.0), None]);
        assert_eq!(quadratic_roots(1.0, 0.0, 1.0), [None, None]);
        // Without cancellation: the small root of s² − 10⁸ s + 1.
        let [small, _] = quadratic_roots(1.0, -1e8, 1.0);
        assert!((small.unwrap() - 1e-8).abs() < 1e-20);
        let f = |x: f64| x * x - 2.0;
        assert!((bisect(&f, 0.0, 2.0, f(0.0)) - 2f64.sqrt()).abs() < 1e-15);
    }
}
