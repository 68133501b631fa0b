//! The Jones polynomial of a knot diagram, by Kauffman's bracket: every way of smoothing each crossing (the
//! A way or the B way), counted by its loops, then normalised by the writhe. It tells a knot from its mirror
//! image, so a square knot from a granny.
//!
//! Owns: [`jones`] and the crossing limit it works to. Must not: allocate (the state sum runs on the stack).

use super::diagram::Diagram;
use super::laurent::Laurent;

/// The most crossings the state sum takes (2^12 states of 24 strands): a square knot has 6, three throws 9.
pub const MAX_BRACKET_CROSSINGS: usize = 12;

/// The Jones polynomial `V(t)` of `diagram` (already simplified), or None if it has more than
/// [`MAX_BRACKET_CROSSINGS`] crossings.
pub fn jones(diagram: &Diagram) -> Option<Laurent> {
    let m = diagram.crossings();
    if m > MAX_BRACKET_CROSSINGS {
        return None;
    }
    let edges = 2 * m;
    // Each crossing's four strands, counterclockwise from the under strand coming in: a, b, c, d.
    let mut corners = [[0u8; 4]; MAX_BRACKET_CROSSINGS];
    let mut under_at = [usize::MAX; MAX_BRACKET_CROSSINGS];
    let mut over_at = [usize::MAX; MAX_BRACKET_CROSSINGS];
    for (k, p) in diagram.code().iter().enumerate() {
        let c = p.crossing as usize;
        if p.over {
            over_at[c] = k;
        } else {
            under_at[c] = k;
        }
    }
    let incoming = |k: usize| ((k + edges - 1) % edges) as u8;
    for c in 0..m {
        let (u, o) = (under_at[c], over_at[c]);
        let (a, cc) = (incoming(u), u as u8);
        let (over_in, over_out) = (incoming(o), o as u8);
        let (b, d) = if diagram.signs()[c] > 0 {
            (over_out, over_in)
        } else {
            (over_in, over_out)
        };
        corners[c] = [a, b, cc, d];
    }
    // counts[A smoothings][loops]
    let mut counts = [[0u64; 2 * MAX_BRACKET_CROSSINGS + 2]; MAX_BRACKET_CROSSINGS + 1];
    for state in 0u32..(1u32 << m) {
        let mut parent = [0u8; 2 * MAX_BRACKET_CROSSINGS];
        for (e, slot) in parent.iter_mut().enumerate().take(edges) {
            *slot = e as u8;
        }
        let mut components = edges.max(1);
        for (c, &[a, b, cc, d]) in corners.iter().enumerate().take(m) {
            let pairs = if state & (1 << c) != 0 {
                [(a, b), (cc, d)] // A
            } else {
                [(a, d), (b, cc)] // B
            };
            for (x, y) in pairs {
                let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
                if rx != ry {
                    parent[rx as usize] = ry;
                    components -= 1;
                }
            }
        }
        let a_count = state.count_ones() as usize;
        counts[a_count][components] += 1;
    }
    // <K> = sum A^(#A - #B) delta^(loops - 1), delta = -A^2 - A^-2.
    let delta = Laurent::from_terms(&[(-1, 2), (-1, -2)]);
    let mut delta_pow = Laurent::one();
    let mut bracket = Laurent::ZERO;
    for loops in 1..=edges.max(1) {
        for (a_count, row) in counts.iter().enumerate().take(m + 1) {
            let n = row[loops];
            if n != 0 {
                let shift = a_count as i32 - (m - a_count) as i32;
                bracket.add_scaled(n as i64, &delta_pow, shift)?;
            }
        }
        delta_pow = delta_pow.mul(&delta)?;
    }
    // V = (-A^3)^-w <K>, then t = A^-4.
    let w = diagram.writhe();
    let sign = if w % 2 == 0 { 1 } else { -1 };
    let mut normalised = Laurent::ZERO;
    normalised.add_scaled(sign, &bracket, -3 * w)?;
    normalised.substitute_power(-4)
}

fn find(parent: &mut [u8], mut x: u8) -> u8 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}
