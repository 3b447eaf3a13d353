"""Formulas within sentences, set in type: the classification, the equilibria, the
Textbook's notes.

The window's sentences are rich text written by many hands (``systems.classification``'s
words, the Textbook tabs' notes). ``formula_spans`` finds the formulas in them: the
textbook's formulas the window writes (``FORMULAS``: ``H = T + V``, ``K v = ω² M v``,
``dH/dt = −∂L/∂t``…), a name with a subscript in HTML (``V<sub>eff</sub>``) and values
given to a name (``θ₁ = 3.142``, ``ω = 2.397, 5.787``). ``latex_of`` writes such text as
LaTeX (Greek letters, subscripts, dots, ∂, Σ).

Their type is set where the derivation's is, in a worker process (``MathStore``: one
job per batch of new formulas, never mathtext on the GUI thread); until it comes, a
formula reads as its text. ``typeset_html`` then puts each formula into the HTML as an
image of its glyphs (scaled to the font, in the text's colour, its baseline on the
line's), inside a link ``tex:N`` that names it, so that a view can copy the formula
under the mouse as LaTeX (``MathLabel``'s context menu, the Derivation tab's).
"""

from __future__ import annotations

import base64
import html
import re
from dataclasses import dataclass

import pyqtgraph as pg
from PySide6.QtCore import QBuffer, QByteArray, QObject, Qt, Signal
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPalette, QTextDocument
from PySide6.QtWidgets import QApplication, QLabel, QMenu, QStyle, QStyledItemDelegate

from systems import processes

INLINE_SCALE = 1.15
"""A formula's em within a sentence, as a multiple of the font's pixel height × 0.82."""

FORMULAS = (
    "v = dr/dt = (∂r/∂q)·q̇ + ∂r/∂t",
    "T = Σ m |v|²/2 = T₂ + T₁ + T₀",
    "p = ∂L/∂q̇ = M q̇ + a",
    "p = dL/dq̇",
    "M q̇ = p − a",
    "M q̈ = F",
    "r = r(q, t)",
    "g(q, t) ≥ 0",
    "−Aᵀ λ",
    "det(−ω² M + iω G + K) = 0",
    "dH/dt = −∂L/∂t + Σ q̇ᵢ Qᵢ",
    "−∂L/∂t + Σ q̇ᵢ Qᵢ",
    "h = Σ q̇ᵢ ∂L/∂q̇ᵢ − L",
    "Σ q̇ᵢ ∂T/∂q̇ᵢ ≠ 2T",
    "R = L − Σ p<sub>c</sub> q̇<sub>c</sub>",
    "∂U/∂q + Aᵀλ = 0",
    "dH/dt = −∂L/∂t",
    "dH/dt = Σ q̇ᵢ Qᵢ",
    "dH/dt = 0",
    "H = T(p) + V(q)",
    "f(q, t) = 0",
    "K v = ω² M v",
    "Σ q̇ᵢ Qᵢ",
    "H = T + V",
    "T = dJ/dE",
    "T → 2π/ω",
    "|tr M| &lt; 2",
    "|tr M| = 2",
    "d²S/dε²",
    "dS/dε",
    "−∂U/∂q",
    "−∂L/∂t",
    "dH/dt",
    "dV/dq = 0",
    "dU/dq = 0",
    "dU/dq",
    "−Aᵀλ",
    "λ ≤ 0",
    "q̇ = 0",
    "r(q, t)",
    "r(q)",
    "O(h²)",
    "dF/dt",
    "T + V",
    "H = E",
    "M(q)",
    "|μ|",
)
"""Formulas the window's sentences write, as they are written (HTML where it has tags)."""

_GREEK = {
    "α": r"\alpha", "β": r"\beta", "γ": r"\gamma", "δ": r"\delta", "ε": r"\varepsilon",
    "ζ": r"\zeta", "η": r"\eta", "θ": r"\theta", "ι": r"\iota", "κ": r"\kappa",
    "λ": r"\lambda", "μ": r"\mu", "ν": r"\nu", "ξ": r"\xi", "π": r"\pi", "ρ": r"\rho",
    "σ": r"\sigma", "τ": r"\tau", "υ": r"\upsilon", "φ": r"\phi", "χ": r"\chi",
    "ψ": r"\psi", "ω": r"\omega", "Γ": r"\Gamma", "Δ": r"\Delta", "Θ": r"\Theta",
    "Λ": r"\Lambda", "Ξ": r"\Xi", "Π": r"\Pi", "Σ": r"\Sigma", "Φ": r"\Phi", "Ψ": r"\Psi",
    "Ω": r"\Omega", "∂": r"\partial", "≤": r"\leq", "≥": r"\geq", "≠": r"\neq",
    "→": r"\to", "−": "-", "·": r"\cdot", "×": r"\times", "≈": r"\approx", "∞": r"\infty",
}  # fmt: skip
_SUBSCRIPTS = str.maketrans("₀₁₂₃₄₅₆₇₈₉ᵢⱼ", "0123456789ij")
_SUPERSCRIPTS = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹ᵀ", "0123456789T")
_SUB = "₀₁₂₃₄₅₆₇₈₉ᵢⱼ"
_SUP = "⁰¹²³⁴⁵⁶⁷⁸⁹ᵀ"
_DOT = "\u0307"
_DDOT = "\u0308"
_HTML_ENTITIES = {"&lt;": "<", "&gt;": ">", "&amp;": r"\&"}


def latex_of(text: str) -> str:
    """A formula written in the window's text (Unicode, ``<sub>``) as LaTeX."""
    for entity, value in _HTML_ENTITIES.items():
        text = text.replace(entity, value)
    text = re.sub(
        r"<sub>([^<]*)</sub>",
        lambda m: "_{" + (m[1] if len(m[1]) == 1 else rf"\mathrm{{{m[1]}}}") + "}",
        text,
    )
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        char = text[i]
        if char in (_DOT, _DDOT) and out:
            out[-1] = (r"\dot{" if char == _DOT else r"\ddot{") + out[-1] + "}"
        elif char in _SUB or char in _SUP:
            marks, table, mark = (
                (_SUB, _SUBSCRIPTS, "_") if char in _SUB else (_SUP, _SUPERSCRIPTS, "^")
            )
            j = i
            while j < n and text[j] in marks:
                j += 1
            out.append(mark + "{" + text[i:j].translate(table) + "}")
            i = j
            continue
        elif char in _GREEK:
            command = _GREEK[char]
            following = text[i + 1 : i + 2]
            out.append(command + (" " if command[-1].isalpha() and following.isalpha() else ""))
        elif text.startswith(("det(", "det ", "tr "), i):
            word = "det" if text.startswith("det", i) else "tr"
            spaced = text[i + len(word)] == " "
            out.append(r"\mathrm{" + word + "}" + (r"\," if spaced else ""))
            i += len(word) + spaced
            continue
        elif char == " ":
            # mathtext drops spaces: a product (``K v``) keeps a thin one
            before, after = "".join(out)[-1:], text[i + 1 : i + 2]
            if (before.isalnum() or before == "}") and (after.isalnum() or after == "∂"):
                out.append(r"\,")
            else:
                out.append(" ")
        else:
            out.append(char)
        i += 1
    return "".join(out)


_NAME = rf"[A-Za-zα-ωΑ-Ω]{_DOT}?[{_SUB}{_SUP}]*"
_NUMBER = r"[−-]?(?:\d+(?:\.\d+)?(?:e[+−-]?\d+)?|π)"
MARKED = re.compile(r'<span class="math">(.*?)</span>', re.DOTALL)
"""A formula marked as such by the code that writes the sentence (``marked``)."""
_PATTERN = re.compile(
    "|".join(re.escape(f) for f in sorted(FORMULAS, key=len, reverse=True))
    + rf"|(?<![\w<>/]){_NAME}<sub>[^<]{{1,6}}</sub>(?: = {_NUMBER}(?!\w|\.\d))?"
    + rf"|(?<![\w.])(?:(?:tr|det) )?{_NAME} = {_NUMBER}(?:, {_NUMBER})*(?!\w|\.\d)"
)
_TAG = re.compile(r"<[^>]*>")


@dataclass(frozen=True)
class Span:
    """A formula in a text: where (``start``, ``end``), as written, and as LaTeX."""

    start: int
    end: int
    text: str
    latex: str


def marked(text: str) -> str:
    """``text`` (a formula in the window's notation, HTML) marked as a formula."""
    return f'<span class="math">{text}</span>'


def formula_spans(html: str) -> list[Span]:
    """The formulas in ``html`` (rich text), in order: those ``marked``, then those
    found (``FORMULAS``, names with values); none inside a tag or a link."""
    spans = [
        Span(m.start(), m.end(), m[1], latex_of(m[1]))
        for m in MARKED.finditer(html)
        if "<" not in _TAG.sub("", m[1])
    ]
    taken = [(span.start, span.end) for span in spans]
    tags = [(m.start(), m.end()) for m in _TAG.finditer(html)]
    links = [(m.start(), m.end()) for m in re.finditer(r"<a\b[^>]*>.*?</a>", html, re.DOTALL)]
    for match in _PATTERN.finditer(html):
        start, end = match.span()
        inside = any(a < end and start < b for a, b in links + taken) or any(
            a < start < b or a < end - 1 < b for a, b in tags if html[a:b] not in _SUB_TAGS
        )
        if inside:
            continue
        spans.append(Span(start, end, match[0], latex_of(match[0])))
    return sorted(spans, key=lambda span: span.start)


_SUB_TAGS = ("<sub>", "</sub>")


# -- the type, from a worker process -------------------------------------------------------


class MathStore(QObject):
    """The type of the window's inline formulas: set in worker processes, kept here.

    ``outline(latex)`` answers from what has been set; a formula not set yet is asked for
    (batched: one worker job for all asked before the event loop runs again) and None is
    answered until ``ready`` is emitted.

    Signals
    -------
    ready()   new formulas have been set in type
    """

    ready = Signal()
    _finished = Signal(object)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self.outlines: dict = {}
        self._asked: set[str] = set()
        self._batch: list[str] = []
        self.jobs: list[processes.Job] = []
        self._batches: dict[int, tuple[str, ...]] = {}
        self._finished.connect(self._on_finished, Qt.ConnectionType.QueuedConnection)

    def outline(self, latex: str):
        """The outline of ``latex`` (``systems.typeset.Outline``), or None while (or if)
        it is not set."""
        found = self.outlines.get(latex)
        if found is None and latex not in self._asked:
            self._asked.add(latex)
            self._batch.append(latex)
            if len(self._batch) == 1:
                from PySide6.QtCore import QTimer

                QTimer.singleShot(0, self._submit)
        return found

    @property
    def pending(self) -> bool:
        """Whether formulas are being set (or about to be)."""
        return bool(self._batch) or any(not job.done() for job in self.jobs)

    def _submit(self) -> None:
        batch, self._batch = tuple(self._batch), []
        if not batch:
            return
        from systems.typeset import outlines_of

        try:
            job = processes.Job(
                outlines_of,
                (batch,),
                cpu_seconds=30.0,
                what="setting formulas in type",
                on_done=self._finished.emit,
            )
        except Exception:  # noqa: BLE001 - no worker: the formulas stay text for now
            self._asked.difference_update(batch)
            return
        self.jobs = [j for j in self.jobs if not j.done()] + [job]
        self._batches[id(job)] = batch

    def _on_finished(self, job) -> None:
        batch = self._batches.pop(id(job), ())
        try:
            found = job.result(0)
        except Exception:  # noqa: BLE001 - cancelled (a window closed) or failed
            self._asked.difference_update(batch)  # asked again when next shown
            return
        self.outlines.update({k: v for k, v in found.items() if v is not None})
        self.ready.emit()

    def cancel(self) -> None:
        """End the jobs in progress (the window closes)."""
        for job in self.jobs:
            job.cancel()
        self.jobs = []


_STORE: MathStore | None = None


def store() -> MathStore:
    """The application's ``MathStore``."""
    global _STORE
    if _STORE is None:
        _STORE = MathStore(QApplication.instance())
    return _STORE


def inline_em(font: QFont, device=None) -> float:
    """A formula's em in a sentence set in ``font``."""
    metrics = QFontMetricsF(font) if device is None else QFontMetricsF(font, device)
    return metrics.height() * 0.82 * INLINE_SCALE


_URLS: dict = {}


def typeset_html(
    html: str, font: QFont, colour: QColor, ratio: float = 1.0, width: float = 0.0
) -> tuple[str, list[Span]]:
    """``html`` with each formula set in ``store()``'s type as an image in a ``tex:N``
    link (N its index in the spans returned); formulas not set yet stay text. A formula
    wider than ``width`` (when given) is drawn smaller to fit it."""
    spans = formula_spans(html)
    if not spans:
        return html, spans
    pieces, at = [], 0
    for index, span in enumerate(spans):
        pieces.append(html[at : span.start])
        at = span.end
        pieces.append(formula_html(span, index, font, colour, ratio, width))
    pieces.append(html[at:])
    return "".join(pieces), spans


def formula_html(
    span: Span, index: int, font: QFont, colour: QColor, ratio: float = 1.0, width: float = 0.0
) -> str:
    """One formula as an image in a ``tex:index`` link, or its text while it is not set
    in type (see ``typeset_html``)."""
    outline = store().outline(span.latex)
    if outline is None:
        return span.text
    size = em = inline_em(font)
    if width > 0 and outline.width * size + 2 > width:
        size = max((width - 2) / outline.width, em * 0.4)
    ascent, descent = outline.ascent * size + 1, outline.descent * size + 1
    # Qt sets an image aligned "middle" with its centre x-height/4 above the baseline:
    # padded so that the formula's baseline lands on the line's
    shift = QFontMetricsF(font).xHeight() / 2.0 - ascent + descent
    top, bottom = max(shift, 0.0), max(-shift, 0.0)
    height = ascent + descent + top + bottom
    url = _padded_url(outline, span.latex, size, colour, ratio, top, bottom)
    return (
        f'<a href="tex:{index}" style="text-decoration:none">'
        f'<img src="{url}" width="{outline.width * size + 2:.1f}" height="{height:.1f}" '
        'style="vertical-align: middle"></a>'
    )


def _padded_url(outline, latex, em, colour, ratio, top, bottom) -> str:
    """The formula's image with ``top`` and ``bottom`` pixels of room."""
    key = ("padded", latex, round(em, 2), colour.rgba(), round(ratio, 2), round(top, 1))
    url = _URLS.get(key)
    if url is not None:
        return url
    from PySide6.QtGui import QPainter, QPixmap

    from explorer.equations import outline_pixmap

    image = outline_pixmap(outline, ("inline", latex), em, colour, ratio)
    width = image.width() / ratio
    height = image.height() / ratio + top + bottom
    padded = QPixmap(max(1, round(width * ratio)), max(1, round(height * ratio)))
    padded.setDevicePixelRatio(ratio)
    padded.fill(Qt.GlobalColor.transparent)
    painter = QPainter(padded)
    painter.drawPixmap(0, round(top), image)
    painter.end()
    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QBuffer.OpenModeFlag.WriteOnly)
    padded.toImage().save(buffer, "PNG")
    url = "data:image/png;base64," + base64.b64encode(bytes(data)).decode("ascii")
    if len(_URLS) > 2000:
        _URLS.clear()
    _URLS[key] = url
    return url


class MathLabel(QLabel):
    """A word-wrapped rich-text label whose formulas are set in type.

    ``setText`` takes the rich text as the window writes it; ``text()`` gives it back
    (the formulas as text). Right-click a formula: Copy as LaTeX, Copy as text. The
    label's own links (``<a href=…>``) still reach ``linkActivated``.

    Signals
    -------
    copied(str)   what was put on the clipboard
    """

    copied = Signal(str)

    def __init__(self, text: str = "", parent=None):
        super().__init__(parent)
        self._source = ""
        self._spans: list[Span] = []
        self._hovered = ""
        self.setWordWrap(True)
        self.setTextFormat(Qt.TextFormat.RichText)
        self.setTextInteractionFlags(Qt.TextInteractionFlag.LinksAccessibleByMouse)
        self.linkHovered.connect(self._on_link_hovered)
        store().ready.connect(self._render)
        self.setText(text)

    def setText(self, text: str) -> None:  # noqa: N802 - Qt override
        self._source = text
        self._render()

    def text(self) -> str:
        return self._source

    def shown_html(self) -> str:
        """The HTML shown (with the formulas' images)."""
        return super().text()

    @property
    def spans(self) -> list[Span]:
        """The formulas found in the text."""
        return list(self._spans)

    def formulas_set(self) -> int:
        """How many of the formulas are shown in type."""
        return super().text().count('href="tex:')

    def _render(self) -> None:
        colour = self.palette().color(QPalette.ColorRole.WindowText)
        ratio = self.devicePixelRatioF() or 1.0
        width = max(self.width() - 12, 0) if self.isVisible() else 0.0
        shown, self._spans = typeset_html(self._source, self.font(), colour, ratio, width)
        super().setText(shown)

    def changeEvent(self, event) -> None:  # noqa: N802 - Qt override
        from PySide6.QtCore import QEvent

        super().changeEvent(event)
        if event.type() in (QEvent.Type.FontChange, QEvent.Type.PaletteChange):
            self._render()

    def _on_link_hovered(self, link: str) -> None:
        self._hovered = link

    def span_at_link(self, link: str) -> Span | None:
        if not link.startswith("tex:"):
            return None
        try:
            return self._spans[int(link[4:])]
        except (ValueError, IndexError):
            return None

    def copy(self, span: Span, latex: bool = True) -> str:
        text = span.latex if latex else _TAG.sub("", span.text).replace("&lt;", "<")
        QApplication.clipboard().setText(text)
        self.copied.emit(text)
        return text

    def context_menu(self) -> QMenu:
        """The menu for the formula under the mouse (Copy as LaTeX, as text)."""
        menu = QMenu(self)
        span = self.span_at_link(self._hovered)
        if span is not None:
            menu.addAction("Copy as LaTeX").triggered.connect(lambda: self.copy(span))
            menu.addAction("Copy as text").triggered.connect(lambda: self.copy(span, False))
        return menu

    def contextMenuEvent(self, event) -> None:  # noqa: N802 - Qt override
        menu = self.context_menu()
        if menu.actions():
            menu.exec(event.globalPos())
        else:
            super().contextMenuEvent(event)


LATEX_ROLE = Qt.ItemDataRole.UserRole + 31
"""A table item's LaTeX when the whole cell is one formula (``MathDelegate``)."""


class MathDelegate(QStyledItemDelegate):
    """Table cells whose text holds formulas, drawn with them set in type (the
    Equilibria tab's frequencies and multipliers; a cell with ``LATEX_ROLE`` data, a
    closed form, as that one formula); other cells as usual."""

    def __init__(self, view):
        super().__init__(view)
        self.view = view
        store().ready.connect(self._on_store_ready)

    def _document(self, option, index) -> QTextDocument | None:
        text = index.data(Qt.ItemDataRole.DisplayRole)
        if not isinstance(text, str) or not text:
            return None
        escaped = html.escape(text, quote=False)
        latex = index.data(LATEX_ROLE)
        whole = Span(0, len(escaped), escaped, latex) if isinstance(latex, str) and latex else None
        if whole is None and not formula_spans(escaped):
            return None
        colour = index.data(Qt.ItemDataRole.ForegroundRole)
        colour = (
            colour.color()
            if hasattr(colour, "color")
            else option.palette.color(QPalette.ColorRole.Text)
        )
        ratio = self.view.devicePixelRatioF() or 1.0
        if whole is not None:
            shown = formula_html(whole, 0, option.font, colour, ratio)
        else:
            shown, _ = typeset_html(escaped, option.font, colour, ratio)
        document = QTextDocument()
        document.setDefaultFont(option.font)
        document.setDocumentMargin(2)
        document.setDefaultStyleSheet(f"body {{ color: {colour.name()}; }}")
        document.setHtml(f"<span style='white-space: pre'>{shown}</span>")
        return document

    def paint(self, painter, option, index) -> None:
        document = self._document(option, index)
        if document is None:
            super().paint(painter, option, index)
            return
        style = option.widget.style() if option.widget is not None else QApplication.style()
        blank = type(option)(option)
        self.initStyleOption(blank, index)
        blank.text = ""
        style.drawControl(QStyle.ControlElement.CE_ItemViewItem, blank, painter, option.widget)
        painter.save()
        top = option.rect.top() + max(0.0, (option.rect.height() - document.size().height()) / 2)
        painter.translate(option.rect.left() + 2, top)
        painter.setClipRect(0, 0, option.rect.width(), option.rect.height())
        document.drawContents(painter)
        painter.restore()

    def sizeHint(self, option, index):  # noqa: N802 - Qt override
        document = self._document(option, index)
        if document is None:
            return super().sizeHint(option, index)
        from PySide6.QtCore import QSize

        size = document.size()
        return QSize(
            int(size.width()) + 6, max(int(size.height()), option.fontMetrics.height() + 6)
        )

    def _on_store_ready(self) -> None:
        try:
            self.view.resizeColumnsToContents()
            self.view.resizeRowsToContents()
            self.view.viewport().update()
        except RuntimeError:  # the table is gone
            pass


class PlotTitle(QObject):
    """A plot's title whose formulas are set in type (``math_title``): ``set`` takes the
    title as ``PlotItem.setTitle`` does, and draws it again once formulas are set."""

    def __init__(self, plot):
        super().__init__(plot)
        self.plot = plot
        self.source: str | None = None
        self.opts: dict = {}
        self.override: dict = {}  # presentation mode's size and colour
        self._set_title = type(plot).setTitle
        store().ready.connect(self.render)

    def set(self, title: str | None = None, **opts) -> None:
        self.source, self.opts = title, opts
        self.render()

    def restyle(self, **override) -> None:
        """Draw the title with ``override`` (``size``, ``color``) over its own options;
        none: its own again."""
        self.override = override
        self.render()

    def render(self) -> None:
        if self.source is None:
            self._set_title(self.plot, None)
            return
        opts = {**self.opts, **self.override}
        font = QFont()
        size = str(opts.get("size", ""))
        if size.endswith("pt"):
            font.setPointSizeF(float(size[:-2]))
        colour = QColor(opts.get("color", "#222"))
        shown, _ = typeset_html(self.source, font, colour)
        self._set_title(self.plot, shown, **opts)

    @property
    def text(self) -> str:
        return self.source or ""


def math_title(plot):
    """Make ``plot``'s (a ``PlotItem``'s) ``setTitle`` set the formulas of its titles in
    type; returns the plot."""
    title = getattr(plot, "math_title", None)
    if title is None:
        title = PlotTitle(plot)
        plot.math_title = title
        plot.setTitle = title.set
    return plot


class MathLabelItem(pg.LabelItem):
    """A pyqtgraph label (a legend's entry) whose formulas are set in type; ``text``
    stays the text as written, so restyling it (presentation mode) sets it again."""

    def __init__(self, text: str = " ", parent=None, angle: int = 0, **args):
        self.source = text
        super().__init__(text, parent, angle, **args)
        store().ready.connect(self._on_store_ready)

    def setText(self, text, **args) -> None:  # noqa: N802 - pyqtgraph's name
        self.source = text
        self.opts.update(args)
        font = QFont()
        size = str(self.opts.get("size") or "")
        if size.endswith("pt"):
            font.setPointSizeF(float(size[:-2]))
        colour = QColor(self.opts.get("color") or pg.getConfigOption("foreground"))
        shown, _ = typeset_html(str(text), font, colour)
        super().setText(shown, **args)
        self.text = text

    def _on_store_ready(self) -> None:
        try:
            self.setText(self.source)
        except RuntimeError:  # the item is gone
            pass


class MathLegend(pg.LegendItem):
    """A legend whose entries' formulas are set in type (``MathLabelItem``)."""

    def _GraphicsWidgetAnchor__geometryChanged(self) -> None:  # noqa: N802 - pyqtgraph's
        """pyqtgraph's anchor follows its ViewBox's geometry; a ViewBox being destroyed
        (its window closing) can still signal once after its wrapper is gone, and the
        anchor's RuntimeError then surfaced in Qt's event loop (a test's teardown, under
        load). The legend goes with it: nothing to move."""
        try:
            super()._GraphicsWidgetAnchor__geometryChanged()
        except RuntimeError:
            pass

    def addItem(self, item, name) -> None:  # noqa: N802 - pyqtgraph's name
        label = MathLabelItem(
            name, color=self.opts["labelTextColor"], justify="left", size=self.opts["labelTextSize"]
        )
        sample = item if isinstance(item, self.sampleType) else self.sampleType(item)
        sample.sigClicked.connect(self.sigSampleClicked)
        self.items.append((sample, label))
        self._addItemToLayout(sample, label)
        self.updateSize()


def math_legend(plot, **options) -> MathLegend:
    """``plot.addLegend(**options)`` with a ``MathLegend``."""
    if plot.legend is None:
        plot.legend = MathLegend(**options)
        plot.legend.setParentItem(plot.vb)
    return plot.legend
