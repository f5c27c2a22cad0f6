//! The Generalized Travelling Salesman Problem: vertices partitioned into
//! sets (clusters), find the shortest closed tour through exactly one vertex
//! of every set. Replanning casts a follow-up flight as one (a cluster of
//! candidate viewpoints per gap voxel); the solver also reads the standard
//! benchmark formats so its quality can be checked against published costs.

mod local;
mod parse;
mod rng;
mod search;
mod solver;

pub use parse::ParseError;
pub use solver::{Solution, SolveOptions, SolveStats, repair, solve};

/// A GTSP instance: integer arc costs between `n` vertices and the sets
/// that partition (a subset of) them. Vertices are 0-based here; the file
/// formats and `postflight gtsp` are 1-based.
#[derive(Debug, Clone)]
pub struct Instance {
    pub name: String,
    n: usize,
    sets: Vec<Vec<u32>>,
    /// The set of each vertex, `u32::MAX` for a vertex in no set.
    set_of: Vec<u32>,
    /// Row-major `n x n` arc costs; `cost[a * n + b]` is the cost of a -> b.
    cost: Vec<i32>,
    symmetric: bool,
}

/// Why an instance cannot be built from the given costs and sets.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InstanceError {
    #[error("the cost matrix has {got} entries, {n} vertices need {}", n * n)]
    MatrixSize { n: usize, got: usize },
    #[error("set {set} is empty; every set needs at least one vertex")]
    EmptySet { set: usize },
    #[error("there are no sets; a GTSP needs at least one")]
    NoSets,
    #[error("vertex {vertex} of set {set} is not a vertex (1..={n})")]
    NoSuchVertex { set: usize, vertex: usize, n: usize },
    #[error(
        "vertex {vertex} is in set {first} and in set {second}; the sets must be disjoint (give each set its own copy of a shared vertex, at cost 0)"
    )]
    SharedVertex {
        vertex: usize,
        first: usize,
        second: usize,
    },
    #[error("the cost from vertex {from} to vertex {to} is negative ({cost})")]
    NegativeCost { from: usize, to: usize, cost: i64 },
}

impl Instance {
    /// Builds an instance from a row-major `n x n` cost matrix (the diagonal
    /// is ignored) and 0-based sets.
    pub fn new(
        name: impl Into<String>,
        n: usize,
        cost: Vec<i32>,
        sets: Vec<Vec<u32>>,
    ) -> Result<Instance, InstanceError> {
        if cost.len() != n * n {
            return Err(InstanceError::MatrixSize { n, got: cost.len() });
        }
        if sets.is_empty() {
            return Err(InstanceError::NoSets);
        }
        let mut set_of = vec![u32::MAX; n];
        for (s, set) in sets.iter().enumerate() {
            if set.is_empty() {
                return Err(InstanceError::EmptySet { set: s + 1 });
            }
            for &v in set {
                let v = v as usize;
                if v >= n {
                    return Err(InstanceError::NoSuchVertex {
                        set: s + 1,
                        vertex: v + 1,
                        n,
                    });
                }
                if set_of[v] != u32::MAX {
                    return Err(InstanceError::SharedVertex {
                        vertex: v + 1,
                        first: set_of[v] as usize + 1,
                        second: s + 1,
                    });
                }
                set_of[v] = s as u32;
            }
        }
        let mut symmetric = true;
        for a in 0..n {
            for b in 0..n {
                let c = cost[a * n + b];
                if a != b && c < 0 {
                    return Err(InstanceError::NegativeCost {
                        from: a + 1,
                        to: b + 1,
                        cost: c.into(),
                    });
                }
                symmetric &= a == b || c == cost[b * n + a];
            }
        }
        Ok(Instance {
            name: name.into(),
            n,
            sets,
            set_of,
            cost,
            symmetric,
        })
    }

    /// Number of vertices.
    pub fn vertices(&self) -> usize {
        self.n
    }

    /// The sets, each a list of 0-based vertices.
    pub fn sets(&self) -> &[Vec<u32>] {
        &self.sets
    }

    /// The set a vertex belongs to, if any.
    pub fn set_of(&self, vertex: u32) -> Option<usize> {
        let s = self.set_of[vertex as usize];
        (s != u32::MAX).then_some(s as usize)
    }

    /// Whether every arc costs the same both ways.
    pub fn is_symmetric(&self) -> bool {
        self.symmetric
    }

    /// Cost of the arc a -> b.
    #[inline]
    pub fn cost(&self, a: u32, b: u32) -> i64 {
        self.cost[a as usize * self.n + b as usize] as i64
    }

    /// Cost of the closed tour through `tour` in order (back to the start).
    pub fn tour_cost(&self, tour: &[u32]) -> i64 {
        match tour.len() {
            0 | 1 => 0,
            len => (0..len)
                .map(|i| self.cost(tour[i], tour[(i + 1) % len]))
                .sum(),
        }
    }

    /// Checks that `tour` visits exactly one vertex of every set; says what
    /// is wrong otherwise.
    pub fn check_tour(&self, tour: &[u32]) -> Result<(), String> {
        let mut seen = vec![false; self.sets.len()];
        for &v in tour {
            if v as usize >= self.n {
                return Err(format!("vertex {} does not exist", v + 1));
            }
            let Some(s) = self.set_of(v) else {
                return Err(format!("vertex {} is in no set", v + 1));
            };
            if std::mem::replace(&mut seen[s], true) {
                return Err(format!("set {} is visited twice", s + 1));
            }
        }
        match seen.iter().position(|&s| !s) {
            Some(s) => Err(format!("set {} is not visited", s + 1)),
            None => Ok(()),
        }
    }
}
