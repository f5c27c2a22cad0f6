//! Union-find (disjoint sets) over `0..n`, with path halving: which
//! observations are one crack, which traced pixels are one piece.

pub struct UnionFind(Vec<u32>);

impl UnionFind {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }

    /// The representative of `i`'s set.
    pub fn root(&mut self, i: usize) -> usize {
        let mut i = i as u32;
        while self.0[i as usize] != i {
            self.0[i as usize] = self.0[self.0[i as usize] as usize];
            i = self.0[i as usize];
        }
        i as usize
    }

    /// Join the sets of `a` and `b`; `false` when they were one already.
    pub fn join(&mut self, a: usize, b: usize) -> bool {
        let (ra, rb) = (self.root(a), self.root(b));
        if ra == rb {
            return false;
        }
        // The smaller index represents: roots do not depend on join order.
        self.0[ra.max(rb)] = ra.min(rb) as u32;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joined_elements_share_a_root_and_others_do_not() {
        let mut sets = UnionFind::new(6);
        assert!(sets.join(0, 1));
        assert!(sets.join(3, 4));
        assert!(sets.join(1, 4));
        assert!(!sets.join(0, 3), "already one set");
        let root = sets.root(4);
        assert!([0, 1, 3, 4].iter().all(|&i| sets.root(i) == root));
        assert_ne!(sets.root(2), root);
        assert_ne!(sets.root(5), sets.root(2));
    }
}
