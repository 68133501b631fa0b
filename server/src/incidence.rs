//! Compressed incidence lists: for each node, the items (springs, triangles, tetrahedra) that touch it.
//!
//! Owns one construction used by the tissue model and the surface collider. [`incidence`] allocates;
//! [`incidence_into`] reuses its output buffers (allocation-free once they have grown).

/// For `n` nodes and items of `K` node indices each: `(start, list)` with the items touching node `i` in
/// `list[start[i]..start[i + 1]]`, in item order. Indices must be `< n`.
pub fn incidence<const K: usize>(n: usize, items: &[[u32; K]]) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; n + 1];
    for item in items {
        for &v in item {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut list = vec![0u32; start[n] as usize];
    for (e, item) in items.iter().enumerate() {
        for &v in item {
            list[fill[v as usize] as usize] = e as u32;
            fill[v as usize] += 1;
        }
    }
    (start, list)
}

/// [`incidence`] into reused buffers, for `count` items given by `item(e)`: no scratch beyond `start` and
/// `list` (items are placed with `start` as cursors, then `start` is shifted back).
pub fn incidence_into<const K: usize>(
    n: usize,
    count: usize,
    item: impl Fn(usize) -> [u32; K],
    start: &mut Vec<u32>,
    list: &mut Vec<u32>,
) {
    start.clear();
    start.resize(n + 1, 0);
    for e in 0..count {
        for v in item(e) {
            start[v as usize + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    list.clear();
    list.resize(start[n] as usize, 0);
    // Place each item at its node's cursor (start[v], advanced), then shift the cursors back by one node.
    for e in 0..count {
        for v in item(e) {
            list[start[v as usize] as usize] = e as u32;
            start[v as usize] += 1;
        }
    }
    for i in (1..=n).rev() {
        start[i] = start[i - 1];
    }
    start[0] = 0;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_every_item_under_each_of_its_nodes() {
        let (start, list) = incidence(4, &[[0, 1, 2], [1, 2, 3]]);
        assert_eq!(start, vec![0, 1, 3, 5, 6]);
        assert_eq!(list, vec![0, 0, 1, 0, 1, 1]);
        let items = [[0u32, 1, 2], [1, 2, 3]];
        let (mut start_into, mut list_into) = (vec![9; 2], vec![7; 9]);
        incidence_into(4, 2, |e| items[e], &mut start_into, &mut list_into);
        assert_eq!((start_into, list_into), (start, list));
    }
}
