//! Charts as inline SVG, drawn on the server: no script, nothing fetched,
//! readable without CSS, styled by class from the stylesheet (the pages'
//! Content-Security-Policy allows no inline style).
//!
//! Every point is a `<circle class="pt">` carrying its data attributes (a
//! calibration id, a run and a position) and a `<title>` read as a tooltip
//! and by screen readers; the page prints the same numbers in a table beside
//! the chart.

use maud::{Markup, html};

use super::format::{date, sig};
use crate::domain::timestamp::Timestamp;

/// Drawing area, in SVG user units.
const W: f64 = 640.0;
const H: f64 = 300.0;
const LEFT: f64 = 92.0;
const RIGHT: f64 = 16.0;
const TOP: f64 = 14.0;
const BOTTOM: f64 = 44.0;

/// One plotted point.
#[derive(Debug, Clone)]
pub struct Point {
    /// Abscissa: seconds since the epoch ([`XAxis::Time`]) or an index.
    pub x: f64,
    /// Ordinate.
    pub y: f64,
    /// Half-length of its error bar, if it has one.
    pub err: Option<f64>,
    /// `data-` attributes (name without the prefix, value).
    pub data: Vec<(&'static str, String)>,
    /// Its tooltip.
    pub label: String,
    /// Drawn as flagged (outside control limits).
    pub flagged: bool,
}

/// Points drawn alike.
#[derive(Debug, Clone)]
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its points.
    pub points: Vec<Point>,
}

/// What the abscissa is.
#[derive(Debug, Clone)]
pub enum XAxis {
    /// Instants, as seconds since the epoch; ticks read as dates.
    Time,
    /// Categories 0, 1, …, named.
    Index(Vec<String>),
}

/// A horizontal line across the chart (a control limit, a centre line).
#[derive(Debug, Clone)]
pub struct Rule {
    /// Its ordinate.
    pub y: f64,
    /// Its legend entry.
    pub label: String,
    /// Its class (`centre`, `limit`).
    pub class: &'static str,
}

/// A straight segment (a fitted drift line).
#[derive(Debug, Clone)]
pub struct Segment {
    /// Start.
    pub from: (f64, f64),
    /// End.
    pub to: (f64, f64),
    /// Its legend entry.
    pub label: String,
    /// Its class (`drift`).
    pub class: &'static str,
}

/// A chart.
#[derive(Debug, Clone)]
pub struct Chart {
    /// Unique within the page (for `aria-labelledby`).
    pub id: String,
    /// Its title (read by screen readers).
    pub title: String,
    /// What the ordinate is.
    pub y_label: String,
    /// What the abscissa is.
    pub x: XAxis,
    /// The series.
    pub series: Vec<Series>,
    /// Horizontal lines.
    pub rules: Vec<Rule>,
    /// Segments.
    pub segments: Vec<Segment>,
}

/// A linear map from data to drawing coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    lo: f64,
    hi: f64,
    from: f64,
    to: f64,
}

impl Scale {
    /// Maps `lo..hi` onto `from..to`.
    pub fn new(lo: f64, hi: f64, from: f64, to: f64) -> Self {
        Scale { lo, hi, from, to }
    }

    /// Where `v` is drawn.
    pub fn at(&self, v: f64) -> f64 {
        self.from + (v - self.lo) / (self.hi - self.lo) * (self.to - self.from)
    }
}

/// The data range widened a little (and made non-empty): `(lo, hi)`.
pub fn padded(values: impl IntoIterator<Item = f64>, min_pad: f64) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc: Option<(f64, f64)>, v| {
            Some(acc.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
        })?;
    let span = hi - lo;
    let pad = if span > 0.0 {
        span * 0.06
    } else {
        (lo.abs() * 1e-3).max(min_pad)
    };
    Some((lo - pad, hi + pad))
}

/// Round tick values covering `lo..=hi`: steps of 1, 2 or 5 × 10ⁿ, about
/// `count` of them; and the step.
pub fn ticks(lo: f64, hi: f64, count: usize) -> (Vec<f64>, f64) {
    let raw = (hi - lo) / count.max(1) as f64;
    if !(raw > 0.0 && raw.is_finite()) {
        return (vec![lo], 0.0);
    }
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    // A bound that is itself a tick (up to rounding) is one.
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    ((first..=last).map(|k| k as f64 * step).collect(), step)
}

/// A tick label with as many decimals as the step needs.
fn tick_label(v: f64, step: f64) -> String {
    let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    if decimals <= 8 && v.abs() < 1e6 {
        format!("{v:.decimals$}")
    } else {
        let magnitude = v.abs().max(step).log10().floor();
        let digits = (magnitude - step.log10().floor()).max(0.0) as usize + 1;
        sig(v, digits)
    }
}

fn seconds_to_date(x: f64) -> String {
    Timestamp::from_unix_micros((x * 1e6) as i64).map_or_else(String::new, |t| date(&t))
}

/// Time-axis ticks on round dates between `lo` and `hi` (seconds since the
/// epoch), about `count` of them: the first of a year (every 1, 2, 5, 10… years,
/// labelled `2019`), of a month (every 1, 3 or 6 months, `2019-04`), or a day
/// (every 1, 2, 7 or 14 days, `2019-04-14`) — whichever step gives no more
/// than `count + 1` ticks, the finest first.
pub fn date_ticks(lo: f64, hi: f64, count: usize) -> Vec<(f64, String)> {
    use time::{Date, Month, OffsetDateTime};
    let at = |d: Date| d.midnight().assume_utc().unix_timestamp() as f64;
    let (Ok(a), Ok(b)) = (
        OffsetDateTime::from_unix_timestamp(lo.floor() as i64),
        OffsetDateTime::from_unix_timestamp(hi.ceil() as i64),
    ) else {
        return vec![];
    };
    let (a, b) = (a.date(), b.date());
    let fits = |n: usize| n <= count + 1;
    for days in [1i64, 2, 7, 14] {
        let first = (at(a) / 86_400.0).ceil() as i64;
        let first = first + (days - first.rem_euclid(days)) % days;
        let ticks: Vec<f64> = (0..)
            .map(|k| (first + k * days) as f64 * 86_400.0)
            .take_while(|x| *x <= hi)
            .filter(|x| *x >= lo)
            .collect();
        if fits(ticks.len()) && !ticks.is_empty() {
            return ticks.into_iter().map(|x| (x, seconds_to_date(x))).collect();
        }
    }
    let months_of = |d: Date| d.year() * 12 + i32::from(u8::from(d.month())) - 1;
    for step in [1i32, 3, 6] {
        let start = months_of(a) + 1;
        let start = start + (step - start.rem_euclid(step)) % step;
        let ticks: Vec<(f64, String)> = (0..)
            .map(|k| start + k * step)
            .take_while(|m| *m <= months_of(b))
            .filter_map(|m| {
                let month = Month::try_from((m.rem_euclid(12) + 1) as u8).ok()?;
                let d = Date::from_calendar_date(m.div_euclid(12), month, 1).ok()?;
                Some((at(d), format!("{}-{:02}", d.year(), u8::from(d.month()))))
            })
            .filter(|(x, _)| *x >= lo && *x <= hi)
            .collect();
        if fits(ticks.len()) && !ticks.is_empty() {
            return ticks;
        }
    }
    let mut step = 1i32;
    loop {
        let first = a.year() + 1;
        let first = first + (step - first.rem_euclid(step)) % step;
        let ticks: Vec<(f64, String)> = (0..)
            .map(|k| first + k * step)
            .take_while(|y| *y <= b.year())
            .filter_map(|y| {
                Some((
                    at(Date::from_calendar_date(y, Month::January, 1).ok()?),
                    y.to_string(),
                ))
            })
            .filter(|(x, _)| *x >= lo && *x <= hi)
            .collect();
        if fits(ticks.len()) || step > 10_000 {
            return ticks;
        }
        step = match step.to_string().as_bytes()[0] {
            b'1' => step * 2,
            b'2' => step * 5 / 2,
            _ => step * 2,
        };
    }
}

/// The chart as an inline SVG figure with its legend.
pub fn render(c: &Chart) -> Markup {
    let points = || c.series.iter().flat_map(|s| s.points.iter());
    let ys = points()
        .flat_map(|p| {
            let e = p.err.unwrap_or(0.0);
            [p.y - e, p.y + e]
        })
        .chain(c.rules.iter().map(|r| r.y))
        .chain(c.segments.iter().flat_map(|s| [s.from.1, s.to.1]));
    let (y_lo, y_hi) = padded(ys, 1e-12).unwrap_or((-1.0, 1.0));
    let (x_lo, x_hi) = match &c.x {
        XAxis::Index(names) => (-0.5, names.len().max(1) as f64 - 0.5),
        XAxis::Time => padded(points().map(|p| p.x), 30.0 * 86_400.0).unwrap_or((0.0, 1.0)),
    };
    let sx = Scale::new(x_lo, x_hi, LEFT, W - RIGHT);
    let sy = Scale::new(y_lo, y_hi, H - BOTTOM, TOP);
    let (y_ticks, y_step) = ticks(y_lo, y_hi, 5);
    let x_ticks: Vec<(f64, String)> = match &c.x {
        XAxis::Index(names) => {
            let every = names.len().div_ceil(12).max(1);
            names
                .iter()
                .enumerate()
                .filter(|(i, _)| i % every == 0)
                .map(|(i, n)| (i as f64, n.clone()))
                .collect()
        }
        XAxis::Time => date_ticks(x_lo, x_hi, 4),
    };
    let title_id = format!("{}-title", c.id);
    html! {
        figure.chart id=(c.id) {
            svg viewBox={"0 0 " (W) " " (H)} role="img" aria-labelledby=(title_id) {
                title id=(title_id) { (c.title) }
                g.grid {
                    @for t in &y_ticks {
                        line x1=(LEFT) x2=(W - RIGHT) y1=(r(sy.at(*t))) y2=(r(sy.at(*t))) {}
                    }
                }
                g.axis {
                    line x1=(LEFT) x2=(LEFT) y1=(TOP) y2=(H - BOTTOM) {}
                    line x1=(LEFT) x2=(W - RIGHT) y1=(H - BOTTOM) y2=(H - BOTTOM) {}
                    @for t in &y_ticks {
                        text.tick x=(LEFT - 6.0) y=(r(sy.at(*t) + 4.0)) text-anchor="end" {
                            (tick_label(*t, y_step))
                        }
                    }
                    @for (x, name) in &x_ticks {
                        text.tick x=(r(sx.at(*x))) y=(H - BOTTOM + 18.0) text-anchor="middle" { (name) }
                    }
                    text.axis-label x=(LEFT) y=(H - 6.0) { (c.y_label) }
                }
                @for rule in &c.rules {
                    line class={"rule " (rule.class)} x1=(LEFT) x2=(W - RIGHT)
                        y1=(r(sy.at(rule.y))) y2=(r(sy.at(rule.y))) {
                        title { (rule.label) }
                    }
                }
                @for seg in &c.segments {
                    line class={"segment " (seg.class)}
                        x1=(r(sx.at(seg.from.0))) y1=(r(sy.at(seg.from.1)))
                        x2=(r(sx.at(seg.to.0))) y2=(r(sy.at(seg.to.1))) {
                        title { (seg.label) }
                    }
                }
                @for (k, s) in c.series.iter().enumerate() {
                    g class={"series s" (k % 6)} data-series=(s.name) {
                        @for p in &s.points {
                            @if let Some(e) = p.err.filter(|e| *e > 0.0) {
                                line.err x1=(r(sx.at(p.x))) x2=(r(sx.at(p.x)))
                                    y1=(r(sy.at(p.y - e))) y2=(r(sy.at(p.y + e))) {}
                            }
                            circle class=(if p.flagged { "pt flagged" } else { "pt" })
                                cx=(r(sx.at(p.x))) cy=(r(sy.at(p.y))) r="4"
                                data-x=(p.x) data-y=(p.y)
                                data-calibration-id=[attr(&p.data, "calibration-id")]
                                data-run=[attr(&p.data, "run")]
                                data-position=[attr(&p.data, "position")] {
                                title { (p.label) }
                            }
                        }
                    }
                }
            }
            figcaption.legend {
                @for (k, s) in c.series.iter().enumerate() {
                    span class={"key s" (k % 6)} { (s.name) }
                }
                @for (k, rule) in c.rules.iter().enumerate() {
                    // One legend entry per kind of line.
                    @if !c.rules[..k].iter().any(|r| r.class == rule.class) {
                        span class={"key " (rule.class)} { (rule.label) }
                    }
                }
                @for seg in &c.segments {
                    span class={"key " (seg.class)} { (seg.label) }
                }
            }
        }
    }
}

fn attr<'a>(data: &'a [(&'static str, String)], name: &str) -> Option<&'a str> {
    data.iter()
        .find(|(n, _)| *n == name)
        .map(|(_, v)| v.as_str())
}

/// A coordinate rounded to 0.01 user units (shorter markup, same picture).
fn r(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_ticks_fall_on_round_dates() {
        let t = |s: &str| Timestamp::parse(s).unwrap().unix_micros() as f64 / 1e6;
        // Seven years: yearly or two-yearly, on 1 January.
        let years = date_ticks(t("2018-03-10T00:00:00Z"), t("2025-08-20T00:00:00Z"), 4);
        let labels: Vec<&str> = years.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["2020", "2022", "2024"]);
        assert_eq!(years[0].0, t("2020-01-01T00:00:00Z"));
        // Ten months: quarterly, on the first of the month.
        let months = date_ticks(t("2019-02-14T00:00:00Z"), t("2019-12-20T00:00:00Z"), 4);
        let labels: Vec<&str> = months.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(labels, ["2019-04", "2019-07", "2019-10"]);
        assert_eq!(months[0].0, t("2019-04-01T00:00:00Z"));
        // Three weeks: weekly, on whole days.
        let days = date_ticks(t("2019-04-03T12:00:00Z"), t("2019-04-24T00:00:00Z"), 4);
        assert!(days.len() <= 5 && days.len() >= 2, "{days:?}");
        assert!(days.iter().all(|(x, _)| x % 86_400.0 == 0.0));
        // Every tick within the range.
        for (x, _) in years.iter().chain(&months).chain(&days) {
            assert!(*x >= t("2018-03-10T00:00:00Z") && *x <= t("2025-08-20T00:00:00Z"));
        }
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let (t, step) = ticks(-1.21620, -1.21610, 5);
        assert!((step - 2e-5).abs() < 1e-18, "{step}");
        assert_eq!(t.len(), 6);
        assert!(
            t.iter()
                .all(|v| (-1.21620 - 1e-12..=-1.21610 + 1e-12).contains(v))
        );
        assert_eq!(tick_label(t[0], step), "-1.21620");
        let (t, step) = ticks(0.0, 10.0, 5);
        assert_eq!((t, step), (vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0], 2.0));
        assert_eq!(ticks(3.0, 3.0, 5).0, vec![3.0]);
    }

    #[test]
    fn scales_map_ends_to_ends() {
        let s = Scale::new(10.0, 20.0, 100.0, 0.0);
        assert_eq!((s.at(10.0), s.at(20.0), s.at(15.0)), (100.0, 0.0, 50.0));
        assert_eq!(padded([2.0, 2.0], 1.0), Some((1.0, 3.0)));
        assert_eq!(padded([0.0, 100.0], 1.0), Some((-6.0, 106.0)));
        assert_eq!(padded([f64::NAN], 1.0), None);
    }

    #[test]
    fn every_point_is_drawn_with_its_data() {
        let chart = Chart {
            id: "c".into(),
            title: "ki over time".into(),
            y_label: "ki".into(),
            x: XAxis::Time,
            series: vec![Series {
                name: "ki".into(),
                points: (0..3)
                    .map(|i| Point {
                        x: 1.0e9 + f64::from(i) * 3.0e7,
                        y: -1.2 + f64::from(i) * 1e-5,
                        err: Some(2e-6),
                        data: vec![("calibration-id", format!("id-{i}"))],
                        label: format!("point {i}"),
                        flagged: i == 2,
                    })
                    .collect(),
            }],
            rules: vec![Rule {
                y: -1.2,
                label: "centre".into(),
                class: "centre",
            }],
            segments: vec![],
        };
        let svg = render(&chart).into_string();
        assert_eq!(svg.matches("<circle").count(), 3);
        for i in 0..3 {
            assert!(
                svg.contains(&format!(r#"data-calibration-id="id-{i}""#)),
                "{svg}"
            );
        }
        assert_eq!(svg.matches("class=\"pt flagged\"").count(), 1);
        assert_eq!(svg.matches("class=\"err\"").count(), 3);
        assert!(
            !svg.contains("style="),
            "no inline style: the CSP forbids it"
        );
        let dates = svg
            .split("text-anchor=\"middle\">")
            .skip(1)
            .filter_map(|t| t.split('<').next())
            .filter(|l| l.len() == 7 && l.as_bytes()[4] == b'-' && l[..4].parse::<i32>().is_ok())
            .count();
        assert!(
            dates >= 3,
            "round dates (year-month) on the time axis: {svg}"
        );
    }
}
