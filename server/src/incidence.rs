//! Compressed incidence lists: for each node, the items (springs, triangles, tetrahedra) that touch it.
//!
//! Owns one construction used by the tissue model and the surface collider. Build-time only (allocates).

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_every_item_under_each_of_its_nodes() {
        let (start, list) = incidence(4, &[[0, 1, 2], [1, 2, 3]]);
        assert_eq!(start, vec![0, 1, 3, 5, 6]);
        assert_eq!(list, vec![0, 0, 1, 0, 1, 1]);
    }
}
