"""Typeset equations in the window and in handouts: the derivation laid out and painted.

The equations come typeset from ``systems.typeset`` (a worker process runs sympy's LaTeX
printer and matplotlib's mathtext): each ``Formula`` holds its LaTeX and the outlines of
its glyphs at font size 1. Here they are only scaled and painted, so nothing here parses
LaTeX or runs sympy:

- ``DerivationLayout`` places a derivation's parts (headings, sentences, formulas, then
  the classification card) in a width, for any paint device, in the device's font and the
  palette's text colour; ``paint`` draws the parts that meet a rectangle.
- On screen each formula is an image (``formula_pixmap``), made from its outline the first
  time it is in sight and kept per (LaTeX, size, colour, device pixel ratio), so
  scrolling a long derivation repaints from images.
- ``write_derivation`` draws the same layout as vectors into a PDF (``QPdfWriter``, A4
  pages) or an SVG (``QSvgGenerator``), or writes the LaTeX document (``.tex``).

A formula without an outline (too large for one line, or LaTeX mathtext refused) is shown
as its wrapped text. Painting never raises into Qt: a formula that fails is drawn as text.
"""

from __future__ import annotations

import html
import math
import weakref
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QMarginsF, QPointF, QRectF, QSizeF, Qt
from PySide6.QtGui import (
    QAbstractTextDocumentLayout,
    QColor,
    QFont,
    QFontMetricsF,
    QPageLayout,
    QPageSize,
    QPainter,
    QPainterPath,
    QPalette,
    QPixmap,
    QTextDocument,
)

from systems.typeset import Formula, Heading, Outline, Sentence, Typeset

MATH_SCALE = 1.2
"""A formula's em as a multiple of the text font's pixel size: Computer Modern looks
smaller than the window's sans-serif at the same size."""

PIXMAPS = 800
"""Formula images kept (``formula_pixmap``): a ten-link chain's derivation is about 100."""

FORMAT_SUFFIXES = (".pdf", ".svg", ".tex")


# -- outlines as paths and images ---------------------------------------------------------

_PATHS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def outline_path(outline: Outline) -> QPainterPath:
    """The glyphs of ``outline`` as a path in ems, y down, baseline at y = 0 (remembered
    while the outline lives)."""
    try:
        return _PATHS[outline]
    except KeyError:
        pass
    path = QPainterPath()
    path.setFillRule(Qt.FillRule.WindingFill)
    vertices, codes = outline.vertices, outline.codes
    i, n = 0, len(codes)
    while i < n:
        code = codes[i]
        x, y = float(vertices[i, 0]), -float(vertices[i, 1])
        if code == 1:
            path.moveTo(x, y)
            i += 1
        elif code == 2:
            path.lineTo(x, y)
            i += 1
        elif code == 3 and i + 1 < n:
            path.quadTo(x, y, float(vertices[i + 1, 0]), -float(vertices[i + 1, 1]))
            i += 2
        elif code == 4 and i + 2 < n:
            path.cubicTo(
                x,
                y,
                float(vertices[i + 1, 0]),
                -float(vertices[i + 1, 1]),
                float(vertices[i + 2, 0]),
                -float(vertices[i + 2, 1]),
            )
            i += 3
        else:  # 79 closes the subpath; 0 (STOP) or a truncated curve ends nothing
            if code == 79:
                path.closeSubpath()
            i += 1
    _PATHS[outline] = path
    return path


_PIXMAPS: OrderedDict = OrderedDict()


def formula_pixmap(formula: Formula, em: float, colour: QColor, ratio: float) -> QPixmap | None:
    """``formula`` as an image: ``em`` logical pixels to the em, in ``colour``, for a
    device pixel ratio ``ratio``; None without an outline. Kept per (LaTeX, size,
    colour, ratio), the last ``PIXMAPS``."""
    if formula.outline is None:
        return None
    return outline_pixmap(formula.outline, formula.latex, em, colour, ratio)


def outline_pixmap(outline: Outline, name, em: float, colour: QColor, ratio: float) -> QPixmap:
    """``outline`` as an image (``formula_pixmap``), kept under ``name`` (its LaTeX, or
    the LaTeX and the index of a piece of it)."""
    key = (name, round(em, 2), colour.rgba(), round(ratio, 2))
    pixmap = _PIXMAPS.get(key)
    if pixmap is not None:
        _PIXMAPS.move_to_end(key)
        return pixmap
    pad = 1.0
    width = math.ceil((outline.width * em + 2 * pad) * ratio)
    height = math.ceil(((outline.ascent + outline.descent) * em + 2 * pad) * ratio)
    pixmap = QPixmap(max(width, 1), max(height, 1))
    pixmap.setDevicePixelRatio(ratio)
    pixmap.fill(Qt.GlobalColor.transparent)
    painter = QPainter(pixmap)
    try:
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        painter.translate(pad, pad + outline.ascent * em)
        painter.scale(em, em)
        painter.fillPath(outline_path(outline), colour)
    finally:
        painter.end()
    _PIXMAPS[key] = pixmap
    while len(_PIXMAPS) > PIXMAPS:
        _PIXMAPS.popitem(last=False)
    return pixmap


# -- the layout ---------------------------------------------------------------------------


@dataclass
class Placed:
    """A part where the layout put it: ``kind`` is ``card``, ``heading``, ``sentence``,
    ``formula`` (typeset) or ``text`` (a formula shown as its text)."""

    kind: str
    part: object
    rect: QRectF
    index: int = -1  # the part's index in the typeset (-1: the card)
    scale: float = 1.0  # a formula shrunk to fit the width
    rows: tuple = ()  # a formula broken across lines: (x, piece indices, baseline) a line


class DerivationLayout:
    """A derivation (a ``Typeset``, or plain text while there is none) and the
    classification card (rich text: the method and the equilibria, after it), laid out
    in a width.

    Sizes follow ``font`` on the paint device (``device``, None for the screen); colours
    come from ``palette``. ``layout(width)`` places every part and returns the height.
    A formula wider than the width is broken across lines where it has pieces
    (``Formula.pieces``: before a term of a sum, after a comma of a tuple), continuation
    lines aligned after its relation, and drawn smaller where a piece is still too wide
    (down to ``LEAST_SCALE``; only past that does the content widen and scroll).
    """

    LEAST_SCALE = 0.45
    LINE_GAP = 0.3  # ems between the lines of a broken formula

    MARGIN = 8.0

    def __init__(self, font: QFont, palette: QPalette, device=None):
        self.font = QFont(font)
        self.palette = palette
        self.device = device
        self.ratio = 1.0  # the screen's device pixel ratio (formulas' images)
        self.typeset: Typeset | None = None
        self.plain = ""  # shown when there is no typeset (``deriving…``, an error)
        self.card_html = ""
        self.placed: list[Placed] = []
        self.width = 0.0
        self.height = 0.0
        self.content_width = 0.0
        self._card: QTextDocument | None = None
        self._rich: dict[int, QTextDocument] = {}  # sentences with formulas, by index
        self.fit = False

    # metrics ---------------------------------------------------------------------------
    def metrics(self, font: QFont) -> QFontMetricsF:
        if self.device is None:
            return QFontMetricsF(font)
        return QFontMetricsF(font, self.device)

    @property
    def em(self) -> float:
        """The formulas' em in layout units."""
        return self.metrics(self.font).height() * 0.82 * MATH_SCALE

    def heading_font(self, level: int) -> QFont:
        font = QFont(self.font)
        font.setBold(True)
        size = font.pointSizeF() if font.pointSizeF() > 0 else 10.0
        font.setPointSizeF(size * (1.3 if level == 0 else 1.08))
        return font

    def note_font(self) -> QFont:
        font = QFont(self.font)
        font.setItalic(True)
        return font

    # layout ----------------------------------------------------------------------------
    def layout(self, width: float) -> float:
        """Place every part in ``width``; returns the height. Content wider than
        ``width`` (a long formula) widens ``content_width``."""
        self.width = width
        m = self.MARGIN
        inner = max(width - 2 * m, 40.0)
        y = m
        right = width
        placed: list[Placed] = []
        if self.typeset is None:
            if self.plain:
                h = self._text_height(self.font, self.plain, inner)
                placed.append(Placed("sentence", self.plain, QRectF(m, y, inner, h)))
                y += h
        else:
            em = self.em
            note_metrics = self.metrics(self.note_font())
            for index, part in enumerate(self.typeset.parts):
                if isinstance(part, Heading):
                    font = self.heading_font(part.level)
                    y += 0.6 * self.metrics(font).height() if index else 0.0
                    rich = self._rich_document(index, part.title, inner, font)
                    if rich is not None:  # a heading with formulas: "p = dL/dq̇"
                        h = rich.size().height()
                        placed.append(Placed("rich", rich, QRectF(m, y, inner, h), index))
                    else:
                        h = self._text_height(font, part.title, inner)
                        placed.append(Placed("heading", part, QRectF(m, y, inner, h), index))
                    y += h + 0.25 * self.metrics(font).height()
                elif isinstance(part, Sentence):
                    rich = self._rich_document(index, part.text, inner)
                    if rich is not None:
                        h = rich.size().height()
                        placed.append(Placed("rich", rich, QRectF(m, y, inner, h), index))
                    else:
                        h = self._text_height(self.font, part.text, inner)
                        placed.append(Placed("sentence", part, QRectF(m, y, inner, h), index))
                    y += h + 0.2 * self.metrics(self.font).height()
                elif isinstance(part, Formula):
                    rect, kind, scale, rows = self._formula_rect(
                        part, m, y, inner, em, note_metrics
                    )
                    placed.append(Placed(kind, part, rect, index, scale, rows))
                    right = max(right, rect.right() + m)
                    y += rect.height()
        if self.card_html:  # after the derivation, as the textbook classifies after deriving
            y += m
            card = self._card_document(inner - 12)
            h = card.size().height() + 12
            placed.append(Placed("card", card, QRectF(m, y, inner, h)))
            y += h
        self.placed = placed
        self.height = y + m
        self.content_width = right
        return self.height

    def _formula_rect(self, part: Formula, x: float, y: float, inner: float, em, notes):
        lead = self._lead(part)
        if part.outline is not None:
            outline = part.outline
            note = em + notes.horizontalAdvance(f"({part.note})") if part.note else 0.0
            room = inner - lead - 2
            if outline.width * em + note <= room:
                w = lead + outline.width * em + 2 + note
                h = (outline.ascent + outline.descent + 0.7) * em
                return QRectF(x, y, w, h), "formula", 1.0, ()
            if part.pieces:
                return self._broken_rect(part, x, y, lead, room, em, note)
            least = 0.05 if self.fit else self.LEAST_SCALE
            scale = max(min((room - note) / (outline.width * em), 1.0), least)
            if scale * outline.width * em > room:  # a note that does not fit goes below
                note = 0.0
            w = lead + outline.width * em * scale + 2 + note
            h = (outline.ascent + outline.descent + 0.7) * em * scale
            return QRectF(x, y, w, h), "formula", scale, ()
        h = self._text_height(self.font, part.text, inner - lead) + 0.5 * em
        return QRectF(x, y, inner, h), "text", 1.0, ()

    def _broken_rect(self, part: Formula, x: float, y: float, lead: float, room: float, em, note):
        """A formula broken across lines: its rect, ``formula``, its scale and rows."""
        pieces = part.pieces
        widths = [piece.width * em for piece in pieces]
        left = sum(widths[: part.lead])
        indent = left if left <= 0.45 * room else 2 * em
        widest = max(widths)
        least = 0.05 if self.fit else self.LEAST_SCALE
        scale = max(min(1.0, room / max(indent + widest, 1e-9)), least)
        rows: list[tuple[float, list[int]]] = [(0.0, [])]
        at = 0.0
        for index, width in enumerate(widths):
            start, held = rows[-1]
            if held and at + width * scale > room:
                rows.append((indent * scale, []))
                at = indent * scale
            rows[-1][1].append(index)
            at += width * scale
        if note and at + note > room:
            rows.append((indent * scale, []))
            at = indent * scale
        ends = [start + sum(widths[i] for i in held) * scale for start, held in rows]
        ends[-1] += note
        right = max(ends)
        placed_rows, depth = [], 0.0
        for start, held in rows:
            shown = [pieces[i] for i in held] or [pieces[-1]]
            ascent = max(piece.ascent for piece in shown)
            baseline = depth + ascent * em * scale
            placed_rows.append((start, tuple(held), baseline))
            depth = baseline + (max(p.descent for p in shown) + self.LINE_GAP) * em * scale
        h = depth + (0.7 - self.LINE_GAP) * em * scale
        return QRectF(x, y, lead + right + 2, h), "formula", scale, tuple(placed_rows)

    def _lead(self, part: Formula) -> float:
        """The room before a formula: its tag (``(1)``) and a gap."""
        if not part.tag:
            return self.em * 0.5
        return self.metrics(self.font).horizontalAdvance(part.tag) + self.em

    def _text_height(self, font: QFont, text: str, width: float) -> float:
        flags = int(Qt.TextFlag.TextWordWrap.value) | int(Qt.AlignmentFlag.AlignLeft.value)
        rect = self.metrics(font).boundingRect(QRectF(0, 0, width, 1e6), flags, text)
        return rect.height()

    def _document(self, html: str, width: float, font: QFont | None = None) -> QTextDocument:
        """Rich text in the layout's font (or ``font``) and text colour; on screen its
        formulas set in type (``explorer.inline_math``; the spans found are its ``spans``)."""
        font = self.font if font is None else font
        document = QTextDocument()
        if self.device is not None:
            document.documentLayout().setPaintDevice(self.device)
        document.setDefaultFont(font)
        document.setDocumentMargin(0)
        colour = self.palette.color(QPalette.ColorRole.Text)
        document.setDefaultStyleSheet(f"body {{ color: {colour.name()}; }}")
        spans = []
        if self.device is None:
            from explorer.inline_math import typeset_html

            html, spans = typeset_html(html, font, colour, self.ratio, width)
        document.spans = spans
        document.setHtml(html)
        document.setTextWidth(max(width, 40.0))
        return document

    def _card_document(self, width: float) -> QTextDocument:
        document = self._card
        if document is None:
            document = self._document(self.card_html, width)
            self._card = document
        document.setTextWidth(max(width, 40.0))
        return document

    def _rich_document(
        self, index: int, text: str, width: float, font: QFont | None = None
    ) -> QTextDocument | None:
        """A sentence or heading with formulas as rich text (None for one without, or off
        screen)."""
        if self.device is not None:
            return None
        document = self._rich.get(index)
        if document is None:
            from explorer.inline_math import formula_spans

            escaped = html.escape(text)
            if not formula_spans(escaped):
                return None
            document = self._document(escaped, width, font)
            self._rich[index] = document
        document.setTextWidth(max(width, 40.0))
        return document

    def inline_at(self, point: QPointF):
        """The inline formula (``explorer.inline_math.Span``) at ``point`` in the card or
        a sentence, or None."""
        for placed in self.placed:
            if placed.kind not in ("card", "rich") or not placed.rect.contains(point):
                continue
            inset = QPointF(6, 6) if placed.kind == "card" else QPointF(0, 0)
            document = placed.part
            link = document.documentLayout().anchorAt(point - placed.rect.topLeft() - inset)
            if link.startswith("tex:"):
                try:
                    return document.spans[int(link[4:])]
                except (ValueError, IndexError, AttributeError):
                    return None
        return None

    def forget_documents(self) -> None:
        """Lay the rich text out again (a new font, palette, or formulas set in type)."""
        self._card = None
        self._rich = {}

    def set_card(self, html_: str) -> None:
        self.card_html = html_
        self._card = None

    def set_font(self, font: QFont) -> None:
        self.font = QFont(font)
        self.forget_documents()

    def set_palette(self, palette: QPalette) -> None:
        self.palette = palette
        self.forget_documents()

    # finding and painting ----------------------------------------------------------
    def at(self, point: QPointF) -> Placed | None:
        """The formula (typeset or as text) at ``point``, or None."""
        for placed in self.placed:
            if placed.kind in ("formula", "text") and placed.rect.contains(point):
                return placed
        return None

    def visible(self, rect: QRectF) -> list[Placed]:
        """The parts that meet ``rect`` (found by bisection: they are in order of y)."""
        placed = self.placed
        lo, hi = 0, len(placed)
        while lo < hi:
            mid = (lo + hi) // 2
            if placed[mid].rect.bottom() < rect.top():
                lo = mid + 1
            else:
                hi = mid
        out = []
        for item in placed[lo:]:
            if item.rect.top() > rect.bottom():
                break
            out.append(item)
        return out

    def paint(
        self, painter: QPainter, rect: QRectF, selected: int = -1, images: bool = True
    ) -> None:
        """Draw the parts that meet ``rect``: formulas as images (``images``, on screen)
        or as vector paths (exports); ``selected`` (a part's index) highlighted."""
        text = self.palette.color(QPalette.ColorRole.Text)
        for item in self.visible(rect):
            try:
                self._paint_item(painter, item, text, item.index == selected >= 0, images)
            except Exception:  # noqa: BLE001 - one bad formula must not stop the others
                painter.save()
                painter.setPen(text)
                painter.setFont(self.font)
                painter.drawText(item.rect, Qt.TextFlag.TextWordWrap, _plain(item.part))
                painter.restore()

    def _paint_item(self, painter: QPainter, item: Placed, text, selected: bool, images) -> None:
        rect = item.rect
        if selected:
            highlight = QColor(self.palette.color(QPalette.ColorRole.Highlight))
            highlight.setAlpha(50)
            painter.fillRect(rect.adjusted(-4, 0, 4, 0), highlight)
        wrap = int(Qt.TextFlag.TextWordWrap.value)
        if item.kind == "rich":
            painter.save()
            painter.translate(rect.left(), rect.top())
            context = QAbstractTextDocumentLayout.PaintContext()
            context.palette = self.palette
            item.part.documentLayout().draw(painter, context)
            painter.restore()
        elif item.kind == "card":
            painter.save()
            painter.setPen(self.palette.color(QPalette.ColorRole.Mid))
            painter.setBrush(self.palette.color(QPalette.ColorRole.AlternateBase))
            painter.drawRoundedRect(rect, 6, 6)
            painter.translate(rect.left() + 6, rect.top() + 6)
            context = QAbstractTextDocumentLayout.PaintContext()
            context.palette = self.palette
            item.part.documentLayout().draw(painter, context)
            painter.restore()
        elif item.kind == "heading":
            painter.setPen(text)
            painter.setFont(self.heading_font(item.part.level))
            painter.drawText(rect, wrap, item.part.title)
        elif item.kind == "sentence":
            painter.setPen(text)
            painter.setFont(self.font)
            painter.drawText(rect, wrap, _plain(item.part))
        elif item.kind == "text":
            self._paint_tag(painter, item.part, rect, text, rect.top() + self.em * 0.25)
            lead = self._lead(item.part)
            painter.setPen(text)
            painter.setFont(self.font)
            body = rect.adjusted(lead, self.em * 0.25, 0, 0)
            painter.drawText(body, wrap, item.part.text)
        elif item.rows:
            self._paint_broken(painter, item, text, images)
        else:
            self._paint_formula(painter, item.part, rect, text, images, item.scale)

    def _paint_broken(self, painter, item: Placed, text, images) -> None:
        """A formula broken across lines: each piece where its row puts it."""
        part, rect = item.part, item.rect
        em = self.em * item.scale
        metrics = self.metrics(self.font)
        top = rect.top() + 0.35 * em
        self._paint_tag(painter, part, rect, text, top + item.rows[0][2] - metrics.ascent())
        left = rect.left() + self._lead(part)
        ratio = painter.device().devicePixelRatioF() if images and painter.device() else 1.0
        x = left
        for start, held, baseline_ in item.rows:
            baseline = top + baseline_
            x = left + start
            for index in held:
                piece = part.pieces[index]
                if images:
                    pixmap = outline_pixmap(piece, (part.latex, index), em, text, ratio)
                    painter.drawPixmap(QPointF(x - 1, baseline - piece.ascent * em - 1), pixmap)
                else:
                    _fill_outline(painter, piece, x, baseline, em, text)
                x += piece.width * em
        if part.note:
            note = f"({part.note})"
            width = self.metrics(self.note_font()).horizontalAdvance(note)
            baseline = top + item.rows[-1][2]
            if not item.rows[-1][1]:
                x = left + item.rows[-1][0]
            else:
                x += self.em
            x = min(x, max(rect.right() - width, left))
            painter.setPen(self.palette.color(QPalette.ColorRole.PlaceholderText))
            painter.setFont(self.note_font())
            painter.drawText(QPointF(x, baseline), note)

    def _paint_formula(self, painter, part: Formula, rect, text, images, scale) -> None:
        em, outline = self.em * scale, part.outline
        top = rect.top() + 0.35 * em
        baseline = top + outline.ascent * em
        metrics = self.metrics(self.font)
        self._paint_tag(painter, part, rect, text, baseline - metrics.ascent())
        x = rect.left() + self._lead(part)
        pixmap = None
        if images:
            ratio = painter.device().devicePixelRatioF() if painter.device() else 1.0
            pixmap = formula_pixmap(part, em, text, ratio)
        if pixmap is not None:
            painter.drawPixmap(QPointF(x - 1, top - 1), pixmap)
        else:  # vectors: exports
            _fill_outline(painter, outline, x, baseline, em, text)
        if part.note:
            note_x = x + outline.width * em + em
            painter.setPen(self.palette.color(QPalette.ColorRole.PlaceholderText))
            painter.setFont(self.note_font())
            painter.drawText(QPointF(note_x, baseline), f"({part.note})")

    def _paint_tag(self, painter, part: Formula, rect: QRectF, text, top: float) -> None:
        if not part.tag:
            return
        painter.setPen(text)
        painter.setFont(self.font)
        metrics = self.metrics(self.font)
        painter.drawText(QPointF(rect.left(), top + metrics.ascent()), part.tag)


def _fill_outline(painter, outline: Outline, x: float, baseline: float, em: float, colour):
    """Draw ``outline`` as vectors, its baseline at (x, baseline), ``em`` units an em."""
    painter.save()
    painter.setRenderHint(QPainter.RenderHint.Antialiasing)
    painter.translate(x, baseline)
    painter.scale(em, em)
    painter.fillPath(outline_path(outline), colour)
    painter.restore()


def _plain(part) -> str:
    if isinstance(part, Sentence):
        return part.text
    if isinstance(part, Formula):
        return part.text
    if isinstance(part, Heading):
        return part.title
    return str(part)


# -- exports --------------------------------------------------------------------------------


def write_derivation(
    typeset: Typeset, path: str | Path, card_html: str = "", font: QFont | None = None
) -> Path:
    """Write the derivation to ``path``: ``.pdf`` (A4 pages, vector), ``.svg`` (one tall
    page, vector) or ``.tex`` (``Typeset.latex_document``). Written whole or not at all.

    Needs a ``QGuiApplication`` for PDF and SVG (the command line starts one offscreen).

    Raises
    ------
    ValueError
        For another suffix.
    OSError
        When the file cannot be written.
    """
    from systems.files import atomic_path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMAT_SUFFIXES:
        raise ValueError(f"{path}: a derivation is written as .pdf, .svg or .tex")
    with atomic_path(path) as temporary:
        if suffix == ".tex":
            Path(temporary).write_text(typeset.latex_document(), encoding="utf-8")
        elif suffix == ".pdf":
            _write_pdf(typeset, str(temporary), card_html, font)
        else:
            _write_svg(typeset, str(temporary), card_html, font)
    return path


def _print_palette() -> QPalette:
    """Black on white, whatever the window's theme: a handout is printed."""
    palette = QPalette()
    for role, colour in (
        (QPalette.ColorRole.Text, "#000000"),
        (QPalette.ColorRole.Mid, "#9aa7b8"),
        (QPalette.ColorRole.AlternateBase, "#f4f7fb"),
        (QPalette.ColorRole.PlaceholderText, "#555555"),
        (QPalette.ColorRole.Highlight, "#ffffff"),
    ):
        palette.setColor(role, QColor(colour))
    return palette


def _handout_font(font: QFont | None) -> QFont:
    font = QFont(font) if font is not None else QFont()
    font.setPointSizeF(10.0)
    return font


RESOLUTION = 96
"""Layout units of the exports, per inch: the page's width in them is its screen width."""


def _write_pdf(typeset: Typeset, path: str, card_html: str, font: QFont | None) -> None:
    from PySide6.QtGui import QPdfWriter

    writer = QPdfWriter(path)
    writer.setResolution(RESOLUTION)
    writer.setTitle(typeset.title)
    writer.setCreator("Phase Explorer")
    layout_ = QPageLayout(
        QPageSize(QPageSize.PageSizeId.A4),
        QPageLayout.Orientation.Portrait,
        QMarginsF(15, 15, 15, 15),
        QPageLayout.Unit.Millimeter,
    )
    writer.setPageLayout(layout_)
    page = writer.pageLayout().paintRectPixels(RESOLUTION)
    layout = DerivationLayout(_handout_font(font), _print_palette(), writer)
    layout.typeset = typeset
    layout.set_card(card_html)
    layout.fit = True
    layout.layout(page.width())
    painter = QPainter(writer)
    try:
        for number, (top, bottom) in enumerate(pages(layout, page.height())):
            if number:
                writer.newPage()
            painter.save()
            painter.setClipRect(QRectF(0, 0, page.width(), bottom - top))
            painter.translate(0, -top)
            layout.paint(painter, QRectF(0, top, page.width(), bottom - top), images=False)
            painter.restore()
    finally:
        painter.end()


def pages(layout: DerivationLayout, height: float) -> list[tuple[float, float]]:
    """Where the pages of ``height`` begin and end: between parts, each page as full as
    the parts allow (a part taller than a page gets a page of its own, cut)."""
    result = []
    top = 0.0
    for item in layout.placed:
        if item.rect.bottom() - top > height and item.rect.top() > top:
            result.append((top, item.rect.top()))
            top = item.rect.top()
    result.append((top, max(layout.height, top + 1.0)))
    return result


def _write_svg(typeset: Typeset, path: str, card_html: str, font: QFont | None) -> None:
    from PySide6.QtCore import QRect, QSize
    from PySide6.QtSvg import QSvgGenerator

    generator = QSvgGenerator()
    generator.setFileName(path)
    generator.setResolution(RESOLUTION)
    generator.setTitle(typeset.title)
    generator.setDescription("The derivation, typeset by Phase Explorer")
    layout = DerivationLayout(_handout_font(font), _print_palette(), generator)
    layout.typeset = typeset
    layout.set_card(card_html)
    width = 760.0
    layout.fit = True
    layout.layout(width)
    size = QSize(math.ceil(width), math.ceil(layout.height))
    generator.setSize(size)
    generator.setViewBox(QRect(0, 0, size.width(), size.height()))
    painter = QPainter(generator)
    try:
        painter.fillRect(QRectF(0, 0, width, layout.height), QColor("white"))
        layout.paint(painter, QRectF(QPointF(0, 0), QSizeF(width, layout.height)), images=False)
    finally:
        painter.end()
