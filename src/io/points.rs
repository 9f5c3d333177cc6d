//! Point lists on disk: CSV with a header naming x, y, z (world RAS mm, any case, any column
//! order); other columns are kept in order; no quoted commas. Every row must have the header's
//! number of cells and finite coordinates.

use crate::error::{Error, Result};
use nalgebra::Vector3;
use std::path::Path;

/// A point CSV, parsed.
#[derive(Clone, Debug)]
pub struct PointTable {
    /// Column names, lower-cased.
    pub header: Vec<String>,
    /// Every row's cells, trimmed.
    pub rows: Vec<Vec<String>>,
    /// Columns of x, y, z.
    pub columns: [usize; 3],
    /// The points, one per row.
    pub points: Vec<Vector3<f64>>,
}

/// Reads a point CSV.
pub fn load_points(path: &Path) -> Result<PointTable> {
    parse_points(path, &super::read_text(path)?)
}

/// Parses the text of the point CSV `path`.
pub fn parse_points(path: &Path, text: &str) -> Result<PointTable> {
    // Spreadsheets write UTF-8 CSV with a byte-order mark before the header.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .ok_or_else(|| Error::bad_file(path, "is empty: a header x,y,z and one point a row"))?
        .1
        .split(',')
        .map(|h| h.trim().to_lowercase())
        .collect();
    let column = |name: &str| -> Result<usize> {
        let mut found = header.iter().enumerate().filter(|(_, h)| *h == name);
        match (found.next(), found.next()) {
            (Some((c, _)), None) => Ok(c),
            (Some(_), Some(_)) => Err(Error::bad_file(
                path,
                format!("names column {name:?} twice"),
            )),
            _ => Err(Error::bad_file(
                path,
                format!("has no column {name:?} in its header"),
            )),
        }
    };
    let columns = [column("x")?, column("y")?, column("z")?];
    let mut lines = lines.peekable();
    if lines.peek().is_none() {
        return Err(Error::bad_file(path, "has a header but no points"));
    }
    let mut rows = Vec::new();
    let mut points = Vec::new();
    for (index, line) in lines {
        let row = index + 1;
        let cells: Vec<String> = line.split(',').map(|c| c.trim().to_string()).collect();
        if cells.len() != header.len() {
            return Err(Error::bad_file(
                path,
                format!(
                    "row {row} has {} cells, its header {}",
                    cells.len(),
                    header.len()
                ),
            ));
        }
        let value = |c: usize| -> Result<f64> {
            cells[c]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    Error::bad_file(
                        path,
                        format!(
                            "row {row}: {} = {:?} is not a finite number",
                            header[c], cells[c]
                        ),
                    )
                })
        };
        points.push(Vector3::new(
            value(columns[0])?,
            value(columns[1])?,
            value(columns[2])?,
        ));
        rows.push(cells);
    }
    Ok(PointTable {
        header,
        rows,
        columns,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spreadsheets_byte_order_mark_and_any_column_order_are_read() {
        let table = parse_points(Path::new("p.csv"), "\u{feff}Name,Z,y,X\nA,3,2,1\n").unwrap();
        assert_eq!(table.columns, [3, 2, 1]);
        assert_eq!(table.points, vec![Vector3::new(1.0, 2.0, 3.0)]);
    }
}
