//! Runs of consecutive numbers, as people and tools write lists of them
//! (`1–4, 7`; Slurm's `--array=1-4,7`).

use std::ops::RangeInclusive;

/// The runs of consecutive numbers in increasing `numbers`, in order.
pub fn consecutive(numbers: &[usize]) -> Vec<RangeInclusive<usize>> {
    let mut runs: Vec<RangeInclusive<usize>> = Vec::new();
    for &n in numbers {
        match runs.last_mut() {
            Some(run) if *run.end() + 1 == n => *run = *run.start()..=n,
            _ => runs.push(n..=n),
        }
    }
    runs
}

/// `runs` written with `dash` inside a run and `separator` between runs.
pub fn write(runs: &[RangeInclusive<usize>], dash: &str, separator: &str) -> String {
    let text: Vec<String> = runs
        .iter()
        .map(|r| {
            if r.start() == r.end() {
                r.start().to_string()
            } else {
                format!("{}{dash}{}", r.start(), r.end())
            }
        })
        .collect();
    text.join(separator)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consecutive_numbers_make_one_run() {
        assert_eq!(consecutive(&[1, 2, 3, 4, 7, 9, 10]), [1..=4, 7..=7, 9..=10]);
        assert_eq!(write(&consecutive(&[1, 2, 3, 7]), "-", ","), "1-3,7");
        assert!(consecutive(&[]).is_empty());
    }
}
