//! Order statistics the stage takes of its measurements.

/// The median (the mean of the middle two of an even count); `None` for none.
pub fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        (values[n / 2 - 1] + values[n / 2]) / 2.0
    })
}

/// A normal error's standard deviation from its absolute `deviations`
/// about the centre: 1.4826 times their median (robust to outliers);
/// `None` for none.
pub fn robust_sigma(deviations: Vec<f64>) -> Option<f64> {
    median(deviations).map(|d| 1.4826 * d)
}

/// The value at quantile `q` (0 to 1) by nearest rank; `None` for none.
pub fn quantile(mut values: Vec<f64>, q: f64) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    let last = values.len().checked_sub(1)?;
    values.get((last as f64 * q).round() as usize).copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_and_quantiles_of_known_values() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(Vec::new()), None);
        let hundred: Vec<f64> = (0..=100).map(f64::from).rev().collect();
        assert_eq!(quantile(hundred.clone(), 0.95), Some(95.0));
        assert_eq!(quantile(hundred, 0.0), Some(0.0));
        assert_eq!(quantile(Vec::new(), 0.5), None);
        assert_eq!(robust_sigma(vec![1.0, 3.0, 2.0]), Some(1.4826 * 2.0));
        assert_eq!(robust_sigma(Vec::new()), None);
    }
}
