//! Connected pieces of a mesh: what the cutting tests count to see a cut part the tissue.

/// Connected pieces of `elements` (elements sharing a vertex are in one piece).
pub fn pieces<const K: usize>(elements: &[[u32; K]], vertices: usize) -> usize {
    let mut parent: Vec<usize> = (0..vertices).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for e in elements {
        for w in &e[1..] {
            let (a, b) = (
                find(&mut parent, e[0] as usize),
                find(&mut parent, *w as usize),
            );
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut roots: Vec<usize> = elements
        .iter()
        .map(|e| find(&mut parent, e[0] as usize))
        .collect();
    roots.sort_unstable();
    roots.dedup();
    roots.len()
}
