//! Laurent polynomials with integer coefficients and a bounded degree, on the stack: the Kauffman bracket in
//! `A` and the Jones polynomial in `t` (`knot/bracket.rs`).
//!
//! Owns: [`Laurent`] (coefficients of `x^-SPAN ..= x^SPAN`). Must not: allocate (it is a fixed array).

/// The largest exponent either way. A diagram of 12 crossings has a bracket within `A^-38 ..= A^38`, and the
/// products the knot catalogue multiplies stay within `t^-28 ..= t^28`.
pub const SPAN: i32 = 64;

const LEN: usize = (2 * SPAN + 1) as usize;

/// `sum c_k x^k` for `k` in `-SPAN ..= SPAN`.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Laurent {
    coef: [i64; LEN],
}

impl std::fmt::Debug for Laurent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut first = true;
        for k in -SPAN..=SPAN {
            let c = self.coef(k);
            if c != 0 {
                if !first {
                    write!(f, " ")?;
                }
                write!(f, "{c:+}x^{k}")?;
                first = false;
            }
        }
        if first {
            write!(f, "0")?;
        }
        Ok(())
    }
}

impl Laurent {
    /// 0.
    pub const ZERO: Laurent = Laurent { coef: [0; LEN] };

    /// `c x^k`. Panics (in tests only: callers keep within the span) if `k` is out of range.
    pub fn monomial(c: i64, k: i32) -> Self {
        let mut p = Self::ZERO;
        p.add_term(c, k);
        p
    }

    /// 1.
    pub fn one() -> Self {
        Self::monomial(1, 0)
    }

    /// From `(coefficient, exponent)` terms.
    pub fn from_terms(terms: &[(i64, i32)]) -> Self {
        let mut p = Self::ZERO;
        for &(c, k) in terms {
            p.add_term(c, k);
        }
        p
    }

    /// The coefficient of `x^k` (0 outside the span).
    pub fn coef(&self, k: i32) -> i64 {
        if (-SPAN..=SPAN).contains(&k) {
            self.coef[(k + SPAN) as usize]
        } else {
            0
        }
    }

    /// Adds `c x^k`; returns false (and changes nothing) if `k` is outside the span.
    pub fn add_term(&mut self, c: i64, k: i32) -> bool {
        if (-SPAN..=SPAN).contains(&k) {
            self.coef[(k + SPAN) as usize] += c;
            true
        } else {
            false
        }
    }

    /// `self * other`, or None if a term of the product falls outside the span.
    pub fn mul(&self, other: &Laurent) -> Option<Laurent> {
        let mut out = Self::ZERO;
        for (i, &a) in self.coef.iter().enumerate() {
            if a == 0 {
                continue;
            }
            for (j, &b) in other.coef.iter().enumerate() {
                if b != 0 && !out.add_term(a * b, i as i32 + j as i32 - 2 * SPAN) {
                    return None;
                }
            }
        }
        Some(out)
    }

    /// `self + c * other * x^shift`, or None if a term falls outside the span.
    pub fn add_scaled(&mut self, c: i64, other: &Laurent, shift: i32) -> Option<()> {
        for (i, &b) in other.coef.iter().enumerate() {
            if b != 0 && !self.add_term(c * b, i as i32 - SPAN + shift) {
                return None;
            }
        }
        Some(())
    }

    /// `p(x^-1)`: the mirror image's polynomial.
    pub fn mirrored(&self) -> Laurent {
        let mut out = Self::ZERO;
        for k in -SPAN..=SPAN {
            out.coef[(-k + SPAN) as usize] = self.coef(k);
        }
        out
    }

    /// The terms `c x^k` with `k` a multiple of `step`, as `c y^(k / step)` with `y = x^step` (negated
    /// exponents when `step` is negative); None if any term's exponent is not a multiple.
    pub fn substitute_power(&self, step: i32) -> Option<Laurent> {
        let mut out = Self::ZERO;
        for k in -SPAN..=SPAN {
            let c = self.coef(k);
            if c != 0 {
                if k % step != 0 {
                    return None;
                }
                out.add_term(c, k / step);
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_mirrors_and_substitution() {
        let trefoil = Laurent::from_terms(&[(1, 1), (1, 3), (-1, 4)]);
        let mirror = trefoil.mirrored();
        assert_eq!(mirror, Laurent::from_terms(&[(1, -1), (1, -3), (-1, -4)]));
        // (t + t^3 - t^4)(t^-1 + t^-3 - t^-4) is its own mirror (the square knot is amphichiral).
        let square = trefoil.mul(&mirror).unwrap();
        assert_eq!(square, square.mirrored());
        assert_eq!(square.coef(0), 3);
        // x^4 + 2 x^-8 -> y - ... with y = x^-4.
        let p = Laurent::from_terms(&[(1, 4), (2, -8)]);
        assert_eq!(
            p.substitute_power(-4).unwrap(),
            Laurent::from_terms(&[(1, -1), (2, 2)])
        );
        assert!(Laurent::from_terms(&[(1, 2)]).substitute_power(4).is_none());
        // Out of span: refused, not wrapped.
        let big = Laurent::monomial(1, SPAN);
        assert!(big.mul(&big).is_none());
    }
}
