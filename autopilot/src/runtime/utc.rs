//! Calendar date and time in UTC from a Unix time, for the names of log files (`2026-12-02_14-31-05.tlog`,
//! `log/2026-12-02/14_31_05.ulg`). UTC rather than local time: the names then sort in flight order
//! whatever the machine's zone or its daylight saving, and the shell needs no time-zone database.

/// A UTC calendar time, to the second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UtcTime {
    pub year: i64,
    pub month: u32,
    pub day: u32,
    pub hour: u32,
    pub minute: u32,
    pub second: u32,
}

impl UtcTime {
    /// The UTC time of `unix_us` µs after 1970-01-01 00:00:00 UTC (leap seconds, as in Unix time, not
    /// counted).
    #[must_use]
    pub fn from_unix_us(unix_us: u64) -> Self {
        let secs = unix_us / 1_000_000;
        let days = (secs / 86_400) as i64;
        let of_day = secs % 86_400;
        // Days to the proleptic Gregorian calendar, counting from 0000-03-01 so that the leap day ends a
        // year, in eras of 400 years (146 097 days).
        let z = days + 719_468;
        let era = z.div_euclid(146_097);
        let day_of_era = z - era * 146_097;
        let year_of_era = (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
        let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
        let month_from_march = (5 * day_of_year + 2) / 153;
        let day = (day_of_year - (153 * month_from_march + 2) / 5 + 1) as u32;
        let month = if month_from_march < 10 { month_from_march + 3 } else { month_from_march - 9 } as u32;
        let year = year_of_era + era * 400 + i64::from(month <= 2);
        Self {
            year,
            month,
            day,
            hour: (of_day / 3600) as u32,
            minute: (of_day / 60 % 60) as u32,
            second: (of_day % 60) as u32,
        }
    }

    /// `YYYY-MM-DD`.
    #[must_use]
    pub fn date(&self) -> String {
        format!("{:04}-{:02}-{:02}", self.year, self.month, self.day)
    }

    /// The time of day with `sep` between hours, minutes and seconds (`14_31_05`, `14-31-05`).
    #[must_use]
    pub fn time(&self, sep: char) -> String {
        format!("{:02}{sep}{:02}{sep}{:02}", self.hour, self.minute, self.second)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(unix_s: u64) -> UtcTime {
        UtcTime::from_unix_us(unix_s * 1_000_000 + 999_999)
    }

    #[test]
    fn known_instants_give_their_calendar_dates() {
        let t = at(0);
        assert_eq!((t.date(), t.time(':')), ("1970-01-01".into(), "00:00:00".into()));
        let t = at(1_796_221_865);
        assert_eq!((t.date(), t.time('_'), t.time('-')), ("2026-12-02".into(), "14_31_05".into(), "14-31-05".into()));
        // A leap day, the second before midnight, and a century that is not a leap year.
        let t = at(951_868_799);
        assert_eq!((t.date(), t.time(':')), ("2000-02-29".into(), "23:59:59".into()));
        assert_eq!(at(4_107_542_400).date(), "2100-03-01");
        assert_eq!(at(4_107_542_399).date(), "2100-02-28");
    }

    #[test]
    fn the_largest_time_does_not_panic() {
        let t = UtcTime::from_unix_us(u64::MAX);
        assert!(t.year > 500_000 && (1..=12).contains(&t.month) && (1..=31).contains(&t.day));
    }
}
