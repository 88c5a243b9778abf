//! Diagnostics: errors and warnings at a span of the source, rendered miette-style
//! (file:line:col, the line, a caret under the span).

use std::fmt;
use std::ops::Range;

use miette::{
    GraphicalReportHandler, GraphicalTheme, LabeledSpan, MietteError, MietteSpanContents,
    SourceCode, SourceSpan, SpanContents,
};

use crate::model::ChartInstance;
use crate::source::Source;

/// How bad a problem is. Errors stop `compile` and make `check` fail; warnings do not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    Error,
    Warning,
}

/// One problem at one place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    pub severity: Severity,
    pub message: String,
    /// Byte span in the source.
    pub span: Range<usize>,
    /// Text under the caret.
    pub label: String,
    pub help: Option<String>,
}

impl Diagnostic {
    pub fn error(span: Range<usize>, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity: Severity::Error,
            message: message.into(),
            span,
            label: String::from("here"),
            help: None,
        }
    }

    pub fn warning(span: Range<usize>, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity: Severity::Warning,
            ..Diagnostic::error(span, message)
        }
    }

    pub fn label(mut self, label: impl Into<String>) -> Diagnostic {
        self.label = label.into();
        self
    }

    pub fn help(mut self, help: impl Into<String>) -> Diagnostic {
        self.help = Some(help.into());
        self
    }

    /// This diagnostic about chart `c`, at a span of the robot file: for a chart an
    /// application declares, moved to the robot's `application` with the place in the
    /// application first, as an error in its XML is (the connection into `input`, if given
    /// and the application made one, else the chart's `FB` element).
    pub fn of_chart(mut self, src: &Source, c: &ChartInstance, input: Option<&str>) -> Diagnostic {
        if let Some(d) = &c.declared {
            let place = input.and_then(|i| d.on.get(i)).unwrap_or(&d.fb);
            self.span = src.span(crate::model::APPLICATION_FILE);
            self.message = format!("{place}: {}", self.message);
            if self.label == "here" {
                self.label = String::from("imported here");
            }
        }
        self
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    /// 1-based line and column of the start of the span.
    pub fn line_col(&self, src: &Source) -> (usize, usize) {
        src.line_col(self.span.start)
    }

    /// `file:line:col: error: message`, one line.
    pub fn short(&self, src: &Source) -> String {
        let (line, col) = self.line_col(src);
        let sev = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        format!("{}:{line}:{col}: {sev}: {}", src.name, self.message)
    }

    /// The full miette rendering: message, `[file:line:col]`, the line and a caret.
    pub fn render(&self, src: &Source, color: bool) -> String {
        let theme = if color {
            GraphicalTheme::unicode()
        } else {
            GraphicalTheme::unicode_nocolor()
        };
        let handler = GraphicalReportHandler::new_themed(theme).with_width(100);
        let span = src.clamp(self.span.clone());
        let excerpt = Excerpt::around(src, span.clone());
        let clamped = Diagnostic {
            span: excerpt.shown_range(excerpt.label.clone()),
            ..self.clone()
        };
        let report = Report {
            d: &clamped,
            src: excerpt,
        };
        let mut out = String::new();
        if handler.render_report(&mut out, &report).is_err() {
            out = self.short(src);
        }
        out
    }
}

struct Report<'a> {
    d: &'a Diagnostic,
    src: Excerpt<'a>,
}

/// Bytes of source a rendering shows at most (its lines with one line of context each
/// side); beyond it only the start of the span and a little either side are shown, so that
/// rendering a diagnostic costs the same on a 60 kB line as on a short one.
pub const EXCERPT_MAX: usize = 1024;
/// Bytes of a long line shown each side of the span when it is cut.
const CUT_CONTEXT: usize = 60;
/// Bytes of a span underlined at most when the excerpt is cut.
const CUT_SPAN: usize = 160;

/// The part of a source a diagnostic shows, with the real offsets, lines and columns
/// (miette reads only this, never the whole text).
struct Excerpt<'a> {
    src: &'a Source,
    /// The bytes shown.
    window: Range<usize>,
    /// The span underlined (inside `window`).
    label: Range<usize>,
    /// The text of `window` as shown: without the carriage returns that end lines (a
    /// Windows file), so that it shows and counts lines as the same file with LF ends.
    /// miette reads it at offsets from `window.start` ([`Excerpt::shown_at`]).
    shown: String,
    /// Where in the source those carriage returns were, in order.
    removed: Vec<usize>,
}

impl<'a> Excerpt<'a> {
    fn around(src: &'a Source, span: Range<usize>) -> Excerpt<'a> {
        let (first, _) = src.line_of(span.start);
        let (last, _) = src.line_of(span.end);
        let from = src.line_start(first.saturating_sub(1));
        let to = src.line_end((last + 1).min(src.line_count().saturating_sub(1)));
        if to - from <= EXCERPT_MAX {
            return Excerpt::new(src, from..to, span);
        }
        // Too much to show: the start of the span on its own line, cut either side.
        let (_, line_start) = src.line_of(span.start);
        let line_end = src.line_end(first);
        let end = src.floor(span.end.min(line_end).min(span.start + CUT_SPAN));
        let window = src.floor(span.start.saturating_sub(CUT_CONTEXT).max(line_start))
            ..src.floor((end + CUT_CONTEXT).min(line_end));
        Excerpt::new(src, window, span.start..end.max(span.start))
    }

    fn new(src: &'a Source, window: Range<usize>, label: Range<usize>) -> Excerpt<'a> {
        let text = src.text.get(window.clone()).unwrap_or("");
        let mut shown = String::with_capacity(text.len());
        let mut removed = Vec::new();
        for (i, c) in text.char_indices() {
            let at = window.start + i;
            if c == '\r' && src.text.as_bytes().get(at + 1) == Some(&b'\n') {
                removed.push(at);
            } else {
                shown.push(c);
            }
        }
        Excerpt {
            src,
            window,
            label,
            shown,
            removed,
        }
    }

    /// Where source offset `at` is in what is shown.
    fn shown_at(&self, at: usize) -> usize {
        at - self.removed.iter().take_while(|&&r| r < at).count()
    }

    /// The source offset of offset `at` of what is shown (the first that shows there: a
    /// line's end is its carriage return, where the same file with LF ends has its LF).
    fn source_at(&self, at: usize) -> usize {
        let mut real = at;
        for &r in &self.removed {
            if r >= real {
                break;
            }
            real += 1;
        }
        real
    }

    /// `range` of the source, in what is shown.
    fn shown_range(&self, range: Range<usize>) -> Range<usize> {
        self.shown_at(range.start)..self.shown_at(range.end)
    }

    /// The text shown of `range` (offsets in what is shown).
    fn text(&self, range: Range<usize>) -> &str {
        let from = |at: usize| at.checked_sub(self.window.start);
        match (from(range.start), from(range.end)) {
            (Some(a), Some(b)) => self.shown.get(a..b).unwrap_or(""),
            _ => "",
        }
    }

    /// 0-based line and column of a byte offset.
    fn line_col0(&self, offset: usize) -> (usize, usize) {
        let (line, col) = self.src.line_col(offset);
        (line - 1, col - 1)
    }
}

impl SourceCode for Excerpt<'_> {
    fn read_span<'b>(
        &'b self,
        span: &SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'b> + 'b>, MietteError> {
        // Offsets in what is shown (see `shown`).
        let (data, at) = if context_lines_before == 0 && context_lines_after == 0 {
            // Where the label starts (miette's `[file:line:col]`).
            let start = self.shown_at(self.src.floor(self.source_at(span.offset())));
            (start..(start + span.len()).max(start), start)
        } else {
            let start = self.window.start;
            (start..start + self.shown.len(), start)
        };
        let (line, column) = self.line_col0(self.source_at(at));
        let text = self.text(data.clone());
        Ok(Box::new(MietteSpanContents::new_named(
            self.src.name.clone(),
            text.as_bytes(),
            SourceSpan::from(data.start..data.end),
            line,
            column,
            text.matches('\n').count() + 1,
        )))
    }
}

impl fmt::Debug for Report<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.d.message)
    }
}

impl fmt::Display for Report<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.d.message)
    }
}

impl std::error::Error for Report<'_> {}

impl miette::Diagnostic for Report<'_> {
    fn severity(&self) -> Option<miette::Severity> {
        Some(match self.d.severity {
            Severity::Error => miette::Severity::Error,
            Severity::Warning => miette::Severity::Warning,
        })
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.d
            .help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn SourceCode> {
        Some(&self.src)
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let span = self.d.span.clone();
        let len = span.end.saturating_sub(span.start);
        Some(Box::new(std::iter::once(LabeledSpan::new(
            Some(self.d.label.clone()),
            span.start,
            len,
        ))))
    }
}

/// Sorts diagnostics by position (then severity) so output is stable.
pub fn sort(diags: &mut [Diagnostic]) {
    diags.sort_by(|a, b| {
        (a.span.start, a.severity, &a.message).cmp(&(b.span.start, b.severity, &b.message))
    });
}

/// Diagnostics rendered in full at most; the rest are counted.
pub const SHOWN: usize = 50;

/// Every diagnostic as `check` prints it: the first [`SHOWN`] rendered, then
/// `... and N more errors` (and warnings) for the rest, then the totals.
pub fn render_all(src: &Source, diags: &[Diagnostic], color: bool) -> String {
    let mut out = String::new();
    for d in diags.iter().take(SHOWN) {
        out.push_str(&d.render(src, color));
        out.push('\n');
    }
    let rest = diags.get(SHOWN..).unwrap_or(&[]);
    let rest_errors = rest.iter().filter(|d| d.is_error()).count();
    let rest_warnings = rest.len() - rest_errors;
    let count = |n: usize, what: &str| match n {
        0 => None,
        1 => Some(format!("1 more {what}")),
        n => Some(format!("{n} more {what}s")),
    };
    let more: Vec<String> = [count(rest_errors, "error"), count(rest_warnings, "warning")]
        .into_iter()
        .flatten()
        .collect();
    if !more.is_empty() {
        out.push_str(&format!("... and {}\n", more.join(" and ")));
    }
    let errors = diags.iter().filter(|d| d.is_error()).count();
    let warnings = diags.len() - errors;
    if !diags.is_empty() {
        out.push_str(&format!(
            "{}: {errors} error(s), {warnings} warning(s)\n",
            src.name
        ));
    }
    out
}
