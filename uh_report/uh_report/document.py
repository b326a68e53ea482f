"""The one renderer of the report pages: Markdown, HTML and CSV of the run and campaign reports.

Texts may hold ``code`` spans (backticks) and **bold**; the HTML renders them as ``<code>`` and
``<strong>``. :class:`Document` is a report as a list of blocks (headings, paragraphs, bullets,
tables, code, figures) rendered to Markdown and to HTML alike (the campaign report); the run report
(:mod:`uh_report.report`) composes its pages from the same pieces: :func:`markdown_table`,
:func:`html_table`, :func:`html_figure`, :func:`html_page`.

Table cells are texts; ``None`` is an empty cell, a :class:`NumberCell` a number the HTML aligns
right (class ``num``, :data:`CSS_NUMBERS`).
"""
from __future__ import annotations

import csv
import html
import io
import re

from uh_runtime.command_line import unwritable_reason

__all__ = ['NumberCell', 'Document', 'inline_html', 'markdown_table', 'html_table', 'html_figure', 'html_page',
           'csv_text', 'make_writable_dir', 'CSS_NUMBERS', 'CSS_CODE']

#: Style of the number cells of a table (:class:`NumberCell`).
CSS_NUMBERS = 'td.num { text-align: right; font-variant-numeric: tabular-nums; }'

#: Style of the code blocks (:meth:`Document.code`).
CSS_CODE = 'pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; }'

# the page's style: the page and its tables, then the extra rules of a page, then the figures
_CSS_TABLES = (
    'body { font-family: sans-serif; margin: 1.5em auto; max-width: 1450px; color: #222; }',
    'table { border-collapse: collapse; margin: 1em 0; }',
    'th, td { border: 1px solid #bbb; padding: 0.3em 0.6em; }',
    'th { background: #eef; }',
)
_CSS_FIGURES = (
    'figure { margin: 1.5em 0; }',
    'img { max-width: 100%; border: 1px solid #ddd; }',
    'figcaption { font-style: italic; margin-top: 0.3em; }',
)


class NumberCell(str):
    """A table cell holding a number: right-aligned in HTML (class ``num``)."""


def inline_html(text, quote: bool = False) -> str:
    """HTML of a text: escaped (quotes too if ``quote``), backtick spans as ``<code>``, ``**bold**`` as ``<strong>``."""
    text = html.escape(str(text), quote=quote)
    text = re.sub(r'`([^`]+)`', r'<code>\1</code>', text)
    return re.sub(r'\*\*([^*]+)\*\*', r'<strong>\1</strong>', text)


def _markdown_row(cells) -> str:
    """One Markdown table row; a ``None`` cell is blank, ``|`` and line breaks in a text are escaped."""
    texts = [' ' if c is None else ' ' + str(c).replace('|', '\\|').replace('\n', ' ') + ' ' for c in cells]
    return '|' + '|'.join(texts) + '|'


def markdown_table(head, rows, right_aligned=()) -> list[str]:
    """Lines of a Markdown table; the columns whose indices are in ``right_aligned`` align right."""
    rule = '|' + ''.join('---:|' if c in right_aligned else '---|' for c in range(len(head)))
    return [_markdown_row(head), rule] + [_markdown_row(row) for row in rows]


def _html_cell(cell, quote: bool) -> str:
    if cell is None:
        return '<td></td>'
    if isinstance(cell, NumberCell):
        return f'<td class="num">{inline_html(cell, quote)}</td>'
    return f'<td>{inline_html(cell, quote)}</td>'


def html_table(head, rows, quote: bool = False) -> str:
    """Return an HTML table of texts (:func:`inline_html`, quotes escaped if ``quote``)."""
    th = ''.join(f'<th>{inline_html(h, quote)}</th>' for h in head)
    body = ''.join('<tr>' + ''.join(_html_cell(c, quote) for c in row) + '</tr>\n' for row in rows)
    return f'<table>\n<thead><tr>{th}</tr></thead>\n<tbody>\n{body}</tbody>\n</table>'


def html_figure(path: str, caption: str, alt: str | None = None) -> str:
    """Return an HTML figure: the image at ``path`` (relative to the page) with its caption."""
    return (f'<figure><img src="{html.escape(path)}" alt="{html.escape(caption if alt is None else alt)}">'
            f'<figcaption>{html.escape(caption)}</figcaption></figure>')


def html_page(title: str, body: str, css=()) -> str:
    """Return a complete HTML page of ``body`` with the reports' style.

    ``css``: further style rules (e.g. :data:`CSS_CODE`).
    """
    style = '\n'.join(_CSS_TABLES + tuple(css) + _CSS_FIGURES)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>\n'
            f'<style>\n{style}\n</style></head>\n<body>\n{body}\n</body></html>\n')


def csv_text(head, rows, value=str) -> str:
    """CSV of a table, each cell written as ``value(cell)``."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow(head)
    for row in rows:
        writer.writerow([value(v) for v in row])
    return out.getvalue()


def make_writable_dir(out, error=ValueError) -> None:
    """Create ``out`` if needed and check that a file can be written in it.

    Raise ``error`` with the reason otherwise.
    """
    if out.exists() and not out.is_dir():
        raise error(f'--out {out}: exists and is not a directory; give a directory')
    reason = unwritable_reason(out)
    if reason is not None:
        raise error(f'--out {out}: cannot write there ({reason})')


class Document:
    """A report as a list of blocks, rendered to Markdown and to HTML alike."""

    def __init__(self):
        self.blocks = []

    def heading(self, level: int, text: str):
        """Add a heading of ``level`` (1 = the title)."""
        self.blocks.append(('heading', level, text))

    def paragraph(self, text: str):
        """Add a paragraph."""
        self.blocks.append(('paragraph', text))

    def bullets(self, items):
        """Add a bullet list."""
        self.blocks.append(('bullets', list(items)))

    def table(self, head, rows):
        """Add a table of texts."""
        self.blocks.append(('table', list(head), [list(r) for r in rows]))

    def code(self, text: str):
        """Add a block of shell commands."""
        self.blocks.append(('code', text))

    def figure(self, path: str, caption: str):
        """Add the image at ``path`` (relative to the report) with its caption."""
        self.blocks.append(('figure', path, caption))

    def markdown(self) -> str:
        """Render the blocks as Markdown."""
        lines = []
        for block in self.blocks:
            kind = block[0]
            if kind == 'heading':
                lines += ['#' * block[1] + ' ' + block[2], '']
            elif kind == 'paragraph':
                lines += [block[1], '']
            elif kind == 'bullets':
                lines += [f'- {item}' for item in block[1]] + ['']
            elif kind == 'table':
                lines += markdown_table(block[1], block[2]) + ['']
            elif kind == 'code':
                lines += ['```bash', block[1], '```', '']
            elif kind == 'figure':
                lines += [f'![{block[2]}]({block[1]})', '', f'*{block[2]}*', '']
        return '\n'.join(lines).rstrip('\n') + '\n'

    def html(self, title: str) -> str:
        """Render the blocks as an HTML page titled ``title``."""
        parts = []
        for block in self.blocks:
            kind = block[0]
            if kind == 'heading':
                parts.append(f'<h{block[1]}>{inline_html(block[2])}</h{block[1]}>')
            elif kind == 'paragraph':
                parts.append(f'<p>{inline_html(block[1])}</p>')
            elif kind == 'bullets':
                parts.append('<ul>' + ''.join(f'<li>{inline_html(i)}</li>' for i in block[1]) + '</ul>')
            elif kind == 'table':
                parts.append(html_table(block[1], block[2]))
            elif kind == 'code':
                parts.append(f'<pre><code>{html.escape(block[1])}</code></pre>')
            elif kind == 'figure':
                parts.append(html_figure(block[1], block[2]))
        return html_page(title, '\n'.join(parts), css=(CSS_CODE,))
