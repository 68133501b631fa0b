//! Connected pieces of a mesh and a closed surface: what the cutting tests check to see a cut part the tissue
//! and leave each piece whole.

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

/// The surface is closed and consistently wound: every directed edge once, with its twin.
pub fn assert_closed_surface(triangles: &[[u32; 3]]) {
    let mut directed: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .collect();
    directed.sort_unstable();
    let unique = {
        let mut d = directed.clone();
        d.dedup();
        d.len()
    };
    assert_eq!(unique, directed.len(), "a directed edge is used twice");
    for [a, b] in &directed {
        assert!(
            directed.binary_search(&[*b, *a]).is_ok(),
            "edge {a}-{b} has no twin: the surface is open"
        );
    }
}
