//! The iteration log: the columns each solver declares, and the sink its lines go to.
//!
//! A solver describes its iteration table once, as a list of [`Column`]s reading an
//! [`IterationRecord`]; [`Table`] formats the header and the rows. Where the lines go is
//! the user's choice ([`LogSink`]): nowhere (the default), standard error, any writer, or
//! a function; library code never prints on its own.

use std::fmt;
use std::io::Write;
use std::sync::{Arc, Mutex};

use super::IterationRecord;

/// How a column prints its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// An integer (the value is a count).
    Count,
    /// Scientific notation with this many digits after the point.
    Sci(usize),
}

/// One column of an iteration table.
#[derive(Debug, Clone, Copy)]
pub struct Column {
    /// Header.
    pub name: &'static str,
    /// Width in characters.
    pub width: usize,
    /// How the value prints.
    pub format: Format,
    /// The value of a record.
    pub value: fn(&IterationRecord) -> f64,
    /// One line saying what the column means (for `--help` texts and documentation).
    pub meaning: &'static str,
}

/// The iteration count, a column of every solver's table.
pub const ITER: Column = Column {
    name: "iter",
    width: 5,
    format: Format::Count,
    value: |r| r.iter as f64,
    meaning: "iterations (steps tried) before this row",
};

/// The cost at the start of the step, a column of every solver's table.
pub const COST: Column = Column {
    name: "cost",
    width: 13,
    format: Format::Sci(6),
    value: |r| r.cost,
    meaning: "total cost at the start of the step",
};

/// An iteration table: header and rows of a solver's declared columns.
#[derive(Debug, Clone, Copy)]
pub struct Table(pub &'static [Column]);

impl Table {
    /// The header line.
    pub fn header(&self) -> impl fmt::Display + '_ {
        Header(self.0)
    }

    /// The line of one record.
    pub fn row<'a>(&'a self, record: &'a IterationRecord) -> impl fmt::Display + 'a {
        Row(self.0, record)
    }

    /// What the columns mean, one line per column.
    pub fn legend(&self) -> String {
        let width = self.0.iter().map(|c| c.name.len()).max().unwrap_or(0);
        self.0
            .iter()
            .map(|c| format!("{:<width$}  {}", c.name, c.meaning))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

struct Header(&'static [Column]);

impl fmt::Display for Header {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, c) in self.0.iter().enumerate() {
            let sep = if i == 0 { "" } else { " " };
            write!(f, "{sep}{:>w$}", c.name, w = c.width)?;
        }
        Ok(())
    }
}

struct Row<'a>(&'static [Column], &'a IterationRecord);

impl fmt::Display for Row<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, c) in self.0.iter().enumerate() {
            let (sep, v, w) = (if i == 0 { "" } else { " " }, (c.value)(self.1), c.width);
            match c.format {
                Format::Count => write!(f, "{sep}{:>w$}", v as u64)?,
                Format::Sci(p) => write!(f, "{sep}{v:>w$.p$e}")?,
            }
        }
        Ok(())
    }
}

/// Where a solver's log lines go.
#[derive(Clone, Default)]
pub enum LogSink {
    /// Nowhere (default).
    #[default]
    Silent,
    /// Standard error.
    Stderr,
    /// Any writer (a file, a buffer), shared.
    Writer(Arc<Mutex<dyn Write + Send>>),
    /// A function receiving each line.
    Function(Arc<dyn Fn(&str) + Send + Sync>),
}

impl fmt::Debug for LogSink {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LogSink::Silent => "Silent",
            LogSink::Stderr => "Stderr",
            LogSink::Writer(_) => "Writer",
            LogSink::Function(_) => "Function",
        })
    }
}

impl LogSink {
    /// Whether lines go anywhere (callers skip formatting otherwise).
    pub fn is_active(&self) -> bool {
        !matches!(self, LogSink::Silent)
    }

    /// Writes one line (without allocating for the silent sink, the standard error and
    /// writers; a function sink receives a formatted string). Write errors are ignored:
    /// a log must not stop a solve.
    pub fn line(&self, args: fmt::Arguments<'_>) {
        match self {
            LogSink::Silent => {}
            LogSink::Stderr => {
                let _ = writeln!(std::io::stderr(), "{args}");
            }
            LogSink::Writer(w) => {
                if let Ok(mut w) = w.lock() {
                    let _ = writeln!(w, "{args}");
                }
            }
            LogSink::Function(f) => f(&args.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const COLUMNS: &[Column] = &[
        ITER,
        Column {
            name: "cost",
            width: 10,
            format: Format::Sci(2),
            value: |r| r.cost,
            meaning: "the cost",
        },
    ];

    #[test]
    fn tables_print_the_declared_columns_to_the_chosen_sink() {
        let table = Table(COLUMNS);
        let record = IterationRecord {
            iter: 3,
            cost: 1234.5,
            ..Default::default()
        };
        assert_eq!(table.header().to_string(), " iter       cost");
        assert_eq!(table.row(&record).to_string(), "    3     1.23e3");
        assert!(table.legend().contains("cost  the cost"));
        let buffer = Arc::new(Mutex::new(Vec::<u8>::new()));
        let sink = LogSink::Writer(buffer.clone());
        sink.line(format_args!("{}", table.row(&record)));
        assert_eq!(
            String::from_utf8(buffer.lock().unwrap().clone()).unwrap(),
            "    3     1.23e3\n"
        );
        let seen = Arc::new(Mutex::new(String::new()));
        let s2 = seen.clone();
        LogSink::Function(Arc::new(move |l| s2.lock().unwrap().push_str(l))).line(format_args!("x{}", 1));
        assert_eq!(*seen.lock().unwrap(), "x1");
        assert!(!LogSink::Silent.is_active() && LogSink::Stderr.is_active());
    }
}
