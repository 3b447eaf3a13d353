"""The main window: editor dock, phase view, configuration and conserved-quantity docks.

Data flow: the editor or the catalogue asks the ``BuildService`` for a scene; a ``Built``
value arrives (compiled off the GUI thread); the window starts a ``SimulationWorker`` for
it in a ``QThread`` and appends each emitted frame to the ``TrajectoryStore``. One
``QTimer`` redraws the visible panels whose data changed, at display rate. A hidden panel
is neither redrawn nor are its diagnostics computed by the worker.

Nothing the user does ends in a traceback the window does not show: a file that cannot be
opened is reported (and the running system kept), a parameter value that would make the
equations singular is refused in the editor, and any other exception escaping a slot or a
thread is shown in the status bar with its traceback behind "Details…". Closing returns
within ``CLOSE_SECONDS``: symbolic work is ended with its process, not waited for.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from PySide6.QtCore import QEvent, QObject, QSize, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence
from PySide6.QtWidgets import (
    QDockWidget,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from explorer.builder import BuildService, Built
from explorer.controls import ControlsPanel
from explorer.editor.editor_panel import SystemEditorPanel
from explorer.envelope import MOMENTA
from explorer.error_report import ErrorReporter
from explorer.gui_gc import GuiThreadCollector
from explorer.panels.chaos_view import attach as attach_chaos_view
from explorer.panels.configuration_view import ConfigurationView
from explorer.panels.conserved_view import ConservedView
from explorer.panels.constraint_forces_view import attach as attach_constraint_view
from explorer.panels.mode_energy_view import attach as attach_mode_view
from explorer.panels.orbit_diagram_view import attach as attach_orbit_diagram
from explorer.panels.phase_view import PhaseView
from explorer.panels.presentation import Presentation
from explorer.panels.window_layout import DockShares, keep_plots_readable
from explorer.preferences import Preferences
from explorer.session.script import line
from explorer.stop_banner import StopBanner, guard_text
from explorer.trajectories import TrajectoryStore
from explorer.wheel_guard import install_wheel_guard
from explorer.worker import RateMeter, RunSettings, SimulationWorker, WorkerThread

REDRAW_MS = 25
FIRST_PAINT_MS = 60
"""After the redraw that holds a new system's first blocks: time for its paint (the
panels repaint at most every 40 ms) before the builder's slower work begins."""
PARAMETER_DEBOUNCE_MS = 80
POINCARE_T_END = 5000.0
CLOSE_SECONDS = 0.8
"""The time closing may take, shared by everything it stops (the requirement is 1 s)."""
MESSAGE_MS = 20000
STATUS_GAP = 14
"""Pixels between the status bar's readouts (time, rate, energy error, method)."""


class Readout(QLabel):
    """A status-bar readout as wide as the widest text it shows (``widest``) in its
    current font: a new value never resizes it, nor cuts it while the bar lays out
    again (presentation mode's larger type included)."""

    def __init__(self, text: str, *, widest: str):
        super().__init__(text)
        self.widest = widest

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt's name
        hint = super().sizeHint()
        margins = self.contentsMargins()
        room = self.fontMetrics().horizontalAdvance(self.widest) + margins.left()
        return QSize(max(hint.width(), room + margins.right() + 2), hint.height())

    def minimumSizeHint(self) -> QSize:  # noqa: N802
        return self.sizeHint()


class MainWindow(QMainWindow):
    """Phase Explorer's window. ``open_scene`` loads a scene; everything else is live.

    Signals
    -------
    system_started(object)  the ``Built`` value of a system whose worker just started
    frame_received()        a worker frame was appended to the store
    acted(str)              a user action the window handled itself, as a line of a session
                            script (docs/sessions.md): open, new, save, export, delete, tab
    """

    system_started = Signal(object)
    frame_received = Signal()
    acted = Signal(str)

    def __init__(self, parent: QWidget | None = None, runs=None):
        super().__init__(parent)
        self.setWindowTitle("Phase Explorer")
        self._runs = runs
        self.energy_tolerance: float | None = RunSettings().energy_tolerance
        self.built: Built | None = None
        self.compiled = None
        self.store = TrajectoryStore()
        self.settings = RunSettings()
        self.runner: WorkerThread | None = None
        self._generation = 0
        self._speed = 1.0
        self.rate_meter = RateMeter()
        self._last_error = math.nan
        self.redraws = 0
        self._frame_due = False  # a new system's first blocks arrived, not yet painted
        self.panel_refreshes = 0  # redraws of the phase view (for the speed benchmark)
        self._closed = False
        self._opening = 0  # the build request of a file being opened, until it reports
        self._stop_shown: tuple | None = None
        self._section_continued = 0  # times Play continued a section run past its end
        self._section_end_shown: tuple | None = None  # the section run end announced last
        self.scene_path: Path | None = None  # the file Save writes (None: ask)
        self.preferences = Preferences()
        self._fresh_next = False  # the editor's next document is a file being opened
        self._fresh_request = 0  # the build request of the file opened last
        self._put_aside: Path | None = None  # where the last replaced unsaved edits went
        self.error_details = ""  # the traceback of the last unexpected error
        self.error_reporter = ErrorReporter(self)
        self.error_reporter.reported.connect(self._on_error_reporter_reported)
        self.error_reporter.install()

        self.builder = BuildService(self)
        self.builder.built.connect(self._on_builder_built)
        self.builder.build_failed.connect(self._on_builder_build_failed)
        self.builder.busy_changed.connect(self._on_builder_busy_changed)
        self.builder.described.connect(self._on_builder_described)
        self.builder.equilibria_found.connect(self._on_builder_equilibria_found)

        self.phase_view = PhaseView()
        self.configuration_view = ConfigurationView()
        self.conserved_view = ConservedView()
        self.editor = SystemEditorPanel()
        self.controls = ControlsPanel()
        # why a run stopped: a strip above the plots, never in the status bar's readouts
        self.stop_banner = StopBanner()
        self.stop_banner.guard_changed.connect(self.set_energy_tolerance)
        self.stop_banner.restart_requested.connect(self._on_stop_banner_restart_requested)
        central = QWidget()
        central.setObjectName("plots-area")
        column = QVBoxLayout(central)
        column.setContentsMargins(0, 0, 0, 0)
        column.setSpacing(2)
        column.addWidget(self.stop_banner)
        column.addWidget(self.phase_view, 1)
        self.setCentralWidget(central)
        self.panels: dict[str, QWidget] = {
            "phase": self.phase_view,
            "configuration": self.configuration_view,
            "conserved": self.conserved_view,
        }
        self.docks: dict[str, QDockWidget] = {}
        self._add_dock("editor", "System editor", self.editor, Qt.DockWidgetArea.LeftDockWidgetArea)
        self._add_dock(
            "configuration",
            "Configuration",
            self.configuration_view,
            Qt.DockWidgetArea.RightDockWidgetArea,
        )
        self._add_dock(
            "conserved",
            "Conserved quantities",
            self.conserved_view,
            Qt.DockWidgetArea.BottomDockWidgetArea,
        )
        self._add_workprecision_dock()
        # the normal-mode energies, in a dock offered where modes apply (lattices, chains)
        self.mode_view = attach_mode_view(self)
        # the constraint forces, in a dock offered for scenes with constraints or particles
        self.constraint_view = attach_constraint_view(self)
        # Lyapunov exponents, MEGNO and SALI as the run plays (View > Chaos)
        self.chaos_view = attach_chaos_view(self)
        # a driven scene's orbit diagram over one parameter (View > Orbit diagram)
        self.orbit_diagram_view = attach_orbit_diagram(self)

        toolbar = self.addToolBar("Run")
        toolbar.setObjectName("run-toolbar")
        toolbar.addWidget(self.controls)
        self._build_status_bar()
        self._build_menus()

        self.editor.scene_edited.connect(self._on_editor_scene_edited)
        self.editor.catalogue_selected.connect(self._on_editor_catalogue_selected)
        self.editor.parameters_changed.connect(self._on_editor_parameters_changed)
        self.editor.parameter_refused.connect(self._on_editor_parameter_refused)
        self.editor.parameter_check = self.parameter_refusal
        self.phase_view.launch_requested.connect(self._on_phase_launch_requested)
        self.phase_view.launch_refused.connect(self._on_phase_launch_refused)
        self.phase_view.mode_changed.connect(self._on_phase_mode_changed)
        self.phase_view.orbit_delete_requested.connect(self.delete_orbit)
        self.controls.method_changed.connect(self._on_controls_method_changed)
        self.controls.notice_posted.connect(self._on_controls_notice_posted)
        self.controls.step_changed.connect(self._on_controls_step_changed)
        self.controls.speed_changed.connect(self._on_controls_speed_changed)
        self.controls.play_toggled.connect(self._on_controls_play_toggled)
        self.controls.single_step_requested.connect(self._on_controls_single_step_requested)
        self.controls.reset_requested.connect(self._on_controls_reset_requested)
        self.controls.clear_requested.connect(self._on_controls_clear_requested)

        self._pending_parameters: dict | None = None
        self.parameter_timer = QTimer(self)
        self.parameter_timer.setSingleShot(True)
        self.parameter_timer.setInterval(PARAMETER_DEBOUNCE_MS)
        self.parameter_timer.timeout.connect(self._on_parameter_timer_timeout)

        self.redraw_timer = QTimer(self)
        self.redraw_timer.setInterval(REDRAW_MS)
        self.redraw_timer.timeout.connect(self._on_redraw_timer_timeout)
        self.redraw_timer.start()
        self.collector = GuiThreadCollector(self)
        self.collector.start()
        from explorer.textbook import install as install_textbook

        self.textbook = install_textbook(self)
        # sized to the screen, each dock its share, no plot crushed below a readable size
        for panel in self.panels.values():
            keep_plots_readable(panel)
        self.dock_shares = DockShares(self)
        self.dock_shares.fit(self.screen().availableGeometry())
        self.presentation = Presentation(self)
        self._build_presentation_menu()
        # Qt runs the filter installed last first: this one shuts down before the
        # Textbook's waits for its computations (which end sooner once the builder stops)
        self.installEventFilter(self)
        self._default_layout = self.saveState()
        install_wheel_guard(self)
        self._connect_tabs()
        from explorer.session import Recorder

        # last: the window's own slots run before the recorder hears of an action
        self.recorder = Recorder(self)

    # -- construction helpers ---------------------------------------------------------------

    def _add_dock(self, key: str, title: str, widget: QWidget, area) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(f"dock-{key}")
        dock.setWidget(widget)
        self.addDockWidget(area, dock)
        dock.visibilityChanged.connect(self._on_dock_visibility_changed)
        self.docks[key] = dock
        return dock

    def _add_workprecision_dock(self) -> None:
        try:
            from explorer.panels.workprecision_view import WorkPrecisionView
        except ImportError:  # the engine's work-precision module is not there yet
            self.workprecision_view = None
            return
        self.workprecision_view = WorkPrecisionView()
        self.panels["workprecision"] = self.workprecision_view
        dock = self._add_dock(
            "workprecision",
            "Work–precision",
            self.workprecision_view,
            Qt.DockWidgetArea.BottomDockWidgetArea,
        )
        self.tabifyDockWidget(self.docks["conserved"], dock)
        self.docks["conserved"].raise_()

    def _build_status_bar(self) -> None:
        bar = self.statusBar()
        self.time_label = Readout("t = 0", widest="t = -8.888e+88")
        self.rate_label = Readout("", widest="8.88e+88 steps/s")
        self.error_label = Readout("", widest="|ΔH/H₀| = 8.88e+88")
        self.method_label = QLabel("")
        self.busy_bar = QProgressBar()
        self.busy_bar.setRange(0, 0)
        self.busy_bar.setMaximumWidth(120)
        self.busy_bar.setVisible(False)
        for widget in (self.time_label, self.rate_label, self.error_label, self.method_label):
            widget.setMinimumWidth(120)
            widget.setContentsMargins(STATUS_GAP, 0, 0, 0)  # never run into the one before
            bar.addPermanentWidget(widget)
        bar.addPermanentWidget(self.busy_bar)
        self.details_button = QPushButton("Details…")
        self.details_button.setToolTip("The traceback of the last unexpected error")
        self.details_button.setVisible(False)
        self.details_button.clicked.connect(self.show_error_details)
        bar.addPermanentWidget(self.details_button)

    def _action(self, menu, text: str, slot, shortcut=None, tip: str = "") -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(QKeySequence(shortcut))
        if tip:
            action.setStatusTip(tip)
        action.triggered.connect(slot)
        menu.addAction(action)
        return action

    def _build_menus(self) -> None:
        menu = self.menuBar()
        file_menu = menu.addMenu("&File")
        self._action(
            file_menu,
            "&New scene",
            self.new_scene,
            QKeySequence.StandardKey.New,
            "Start a blank system in the editor",
        )
        self._action(
            file_menu,
            "&Open scene…",
            self._on_open_triggered,
            QKeySequence.StandardKey.Open,
            "Open a scene file (.toml)",
        )
        self.recent_menu = file_menu.addMenu("Open &recent")
        self.recent_menu.aboutToShow.connect(self._fill_recent_menu)
        file_menu.addSeparator()
        self._action(
            file_menu,
            "&Save scene",
            self._on_save_triggered,
            QKeySequence.StandardKey.Save,
            "Write what the editor holds to the scene's file",
        )
        self._action(
            file_menu,
            "Save scene &as…",
            self._on_save_as_triggered,
            QKeySequence.StandardKey.SaveAs,
            "Write what the editor holds to a new scene file",
        )
        self._action(
            file_menu,
            "Save sess&ion…",
            self._on_save_session_triggered,
            None,
            "Write what you did in this window as a session script to replay (docs/sessions.md)",
        )
        file_menu.addSeparator()
        export_menu = file_menu.addMenu("&Export")
        self.export_actions = {}
        shortcuts = {"phase": "Ctrl+E", "configuration": "Ctrl+Shift+G", "conserved": None}
        for key, title in (
            ("phase", "Phase view"),
            ("configuration", "Configuration view"),
            ("conserved", "Conserved quantities"),
            ("workprecision", "Work–precision"),
        ):
            if key not in self.panels:
                continue
            self.export_actions[key] = self._action(
                export_menu,
                f"{title} as PNG or SVG…",
                lambda _=False, k=key: self.export_panel_dialog(k),
                shortcuts.get(key),
                f"Write the {title.lower()} as a PNG image or an SVG drawing",
            )
        self.csv_action = self._action(
            export_menu,
            "Trajectories as CSV…",
            self._on_export_csv_triggered,
            "Ctrl+Shift+E",
            "Write every orbit's t, q, q_dot, p and H as CSV",
        )
        file_menu.addSeparator()
        self._action(file_menu, "&Quit", self.close, QKeySequence.StandardKey.Quit)
        run_menu = menu.addMenu("&Run")
        self._action(run_menu, "Play / pause", self.controls.play_button.toggle, "Space")
        # through the toolbar's widgets: the same path (and the same session line) as a click
        self._action(run_menu, "Single step", self.controls.single_step_requested.emit, "Ctrl+.")
        self._action(run_menu, "Reset", self.controls.reset_button.click, "Ctrl+R")
        self._action(
            run_menu, "Clear launched orbits", self.controls.clear_button.click, "Ctrl+Shift+K"
        )
        run_menu.addSeparator()
        self.energy_guard_action = self._action(
            run_menu,
            "Energy guard…",
            self._on_energy_guard_triggered,
            None,
            "Stop a run whose relative energy error exceeds a bound, or whose motion grows "
            "without bound",
        )
        self._show_energy_guard()
        run_menu.addSeparator()
        fill = self.phase_view.fill_layer  # the phase view's "Fill section…", and its stop
        run_menu.addAction(fill.fill_action)
        run_menu.addAction(fill.stop_action)
        fill.message.connect(self.statusBar().showMessage)
        self.view_menu = menu.addMenu("&View")
        for dock in self.docks.values():
            self.view_menu.addAction(dock.toggleViewAction())
        self.view_menu.addSeparator()
        self._action(
            self.view_menu,
            "Reset &layout",
            self.reset_layout,
            "Ctrl+Shift+L",
            "Put every panel that applies to this system back where it was at the start",
        )
        help_menu = menu.addMenu("&Help")
        self._action(
            help_menu, "Quick &tour", self.show_quick_tour, QKeySequence.StandardKey.HelpContents
        )
        self._action(help_menu, "&Scene format", self.show_scene_format)
        self._action(help_menu, "&Session scripts", self.show_session_format)
        toolbar = self.addToolBar("Export")
        toolbar.setObjectName("export-toolbar")
        toolbar.addAction(self.export_actions["phase"])
        toolbar.addAction(self.csv_action)
        self.export_actions["phase"].setText("Export figure")
        self.export_actions["phase"].setToolTip("Export the phase view as PNG or SVG (Ctrl+E)")
        self.csv_action.setText("Export CSV")
        self.csv_action.setToolTip("Export every orbit as CSV (Ctrl+Shift+E)")

    # -- opening systems ----------------------------------------------------------------------

    def open_scene(self, scene) -> int:
        """Open a catalogue name, a path or a ``Scene``: shown in the editor, built, run.

        Returns the build request, or 0 if the file could not be read. A file that cannot
        be read or built is reported in the window (status bar and editor), never raised,
        and the system running before keeps running, with the editor showing it again.
        A scene opened from a file of the user's becomes the file Save writes.
        """
        from systems.scene import SCENES_DIR, Scene, SceneError, load_scene

        if not isinstance(scene, Scene):
            name = str(scene)
            try:
                scene = load_scene(scene)
            except SceneError as exc:
                self._refuse_opening(str(exc))
                return 0
            except (OSError, ValueError, RecursionError, MemoryError) as exc:
                self._refuse_opening(f"{scene}: the file cannot be read: {exc}")
                return 0
            self.acted.emit(line("open", name))
        source = getattr(scene, "source", None)
        path = Path(source).resolve() if source else None
        if path is not None and path.is_file() and path.parent != SCENES_DIR:
            self.scene_path = path
            self.preferences.add_recent(path)
        else:
            self.scene_path = None  # a catalogue scene is never overwritten: Save asks
        self._put_aside_typed_work()
        self.editor.show_scene(scene)
        self._opening = self.builder.request(scene)
        return self._opening

    def _put_aside_typed_work(self) -> Path | None:
        """Before the editor's document is replaced: if it holds typed changes that were
        not saved, write it to the preferences folder's ``unsaved/``, put it first in
        Open recent, and say so. Typed work is never lost, and no dialog interrupts."""
        if not self.editor.typed_changes:
            return None
        from systems.files import atomic_path

        title = _file_name(self.editor)[: -len(".toml")]
        folder = self.preferences.path.parent / "unsaved"
        path = folder / f"{title}-{time.strftime('%Y%m%d-%H%M%S')}.toml"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with atomic_path(path) as temporary:
                temporary.write_text(self.editor.document_text(), encoding="utf-8")
        except OSError as exc:
            self.statusBar().showMessage(f"could not keep the unsaved edits: {exc}", MESSAGE_MS)
            return None
        self.preferences.add_recent(path)
        self._put_aside = path
        self.statusBar().showMessage(
            f"your unsaved edits are kept in {path} (File > Open recent)", MESSAGE_MS
        )
        return path

    def open_file(self, path: str | Path) -> int:
        """File > Open: show a scene file of the user's in the editor and build it.

        Unlike ``open_scene`` (the catalogue), the file need not be a valid scene yet: a
        document saved unfinished opens with its errors under the fields, so that it can
        be finished. Until it builds, the system running before keeps running. A file
        that is not text, or not TOML, is refused and the editor keeps what it had.
        Returns the build request, or 0 if the file was refused.
        """
        from systems.scene import SceneError, read_scene_file

        self._put_aside_typed_work()
        self._fresh_next = True
        try:
            self.editor.show_document(read_scene_file(path), source=str(path))
        except SceneError as exc:
            self._refuse_opening(str(exc))
            return 0
        finally:
            self._fresh_next = False
        self.acted.emit(line("open", str(path)))
        self.scene_path = Path(path).resolve()
        self.preferences.add_recent(self.scene_path)
        return self._fresh_request

    def new_scene(self) -> None:
        """File > New scene: a blank template in the editor, built as soon as it builds."""
        self.acted.emit("new")
        self._put_aside_typed_work()
        self.scene_path = None
        self.editor.new_scene()
        self.docks["editor"].show()
        self.docks["editor"].raise_()

    def _refuse_opening(self, message: str) -> None:
        """Say that a file was not opened; the running system and the editor stay."""
        self.editor.show_failure_message(f"not opened: {message}")
        self.statusBar().showMessage(f"not opened: {message}", MESSAGE_MS)

    def _on_editor_catalogue_selected(self, name: str) -> None:
        self.open_scene(name)

    def _on_editor_scene_edited(self, document) -> None:
        request = self.builder.request(document)
        if self._fresh_next:
            self._fresh_request = request  # a file opened: its system starts clean

    def _on_builder_busy_changed(self, busy: bool) -> None:
        self.busy_bar.setVisible(busy)

    def _on_builder_equilibria_found(self, _request: int, lines: list) -> None:
        self.editor.show_equilibria(lines)

    def _on_builder_described(self, _request: int, text: str) -> None:
        self.editor.show_derivation(text)

    def _on_builder_build_failed(self, failure) -> None:
        if failure.request == self._opening and self.built is not None:
            # an opened file that does not build: back to the system that is running
            self._opening = 0
            self.editor.restore_previous()
            self._refuse_opening(failure.message)
            return
        self._opening = 0
        self.editor.show_failure(failure)
        self.statusBar().showMessage(failure.message, MESSAGE_MS)

    def _on_builder_built(self, built: Built) -> None:
        if self._closed:
            return
        previous = self.built
        opened = built.request in (self._opening, self._fresh_request)
        self._opening = 0
        # a new system (opened, or edited into other coordinates) starts clean: the
        # method, step and section chosen for the last one do not carry over, nor do its
        # messages; an edit of the same system keeps what still applies
        fresh = (
            opened
            or previous is None
            or tuple(previous.scene.coordinates) != tuple(built.scene.coordinates)
        )
        self.built = built
        self.editor.show_built(built)
        from systems.integrators import STEPPERS

        self.controls.set_methods(
            STEPPERS, built.compiled.mechanics, built.method, built.reason, keep=not fresh
        )
        if fresh:
            if not self.controls.playing:  # a new system starts running
                self.controls.play_button.blockSignals(True)
                self.controls.play_button.setChecked(True)
                self.controls.play_button.blockSignals(False)
                self.controls.refresh_play_button()
            self.phase_view.blockSignals(True)  # the new system is started just below
            self.phase_view.set_mode("phase")
            self.phase_view.blockSignals(False)
            self.statusBar().clearMessage()
            if self._put_aside is not None:  # the one message that outlives the old system
                self.statusBar().showMessage(
                    f"your unsaved edits are kept in {self._put_aside} (File > Open recent)",
                    MESSAGE_MS,
                )
                self._put_aside = None
            self.details_button.setVisible(False)
        self.setWindowTitle(f"Phase Explorer — {built.scene.title}")
        self._start_system(built.compiled, launches=None)
        if self.workprecision_view is not None:
            self.workprecision_view.set_system(built.compiled)
        self.system_started.emit(built)

    def parameter_refusal(self, values: dict) -> str | None:
        """Why the running system cannot take these parameter values, or None if it can.

        The editor asks before sending them on: a value that is not finite, or that makes
        the equations singular at the start (a zero length or mass), is refused there.
        """
        from systems.start_check import SingularStart, check_start

        if self.compiled is None:
            return None
        known = {k: v for k, v in values.items() if k in self.compiled.parameter_names}
        bad = [k for k, v in known.items() if not math.isfinite(v)]
        if bad:
            return f"{', '.join(bad)}: a parameter value must be a finite number"
        try:
            check_start(self.compiled.with_parameters(known))
        except SingularStart as exc:
            return exc.reason
        return None

    def _on_editor_parameter_refused(self, message: str) -> None:
        self.statusBar().showMessage(message, MESSAGE_MS)

    def _on_editor_parameters_changed(self, values: dict) -> None:
        if self.statusBar().currentMessage() == self.editor.last_refusal:
            self.statusBar().clearMessage()  # an accepted value answers the refusal
        # a dragged slider sends many values: restart once it rests for a moment
        self._pending_parameters = values
        self.parameter_timer.start()

    def _on_parameter_timer_timeout(self) -> None:
        values, self._pending_parameters = self._pending_parameters, None
        if self.compiled is None or not values:
            return
        known = {k: v for k, v in values.items() if k in self.compiled.parameter_names}
        compiled = self.compiled.with_parameters(known)
        self._start_system(compiled, launches=self._launch_states())

    def _launch_states(self) -> list[np.ndarray]:
        return [trajectory.y0 for trajectory in self.store if trajectory.key != 0]

    # -- running -----------------------------------------------------------------------------

    def _current_settings(self) -> RunSettings:
        poincare = self.phase_view.mode == "poincare"
        method = self.controls.method or (self.built.method if self.built else None) or None
        section = None
        if poincare and self.phase_view.section is not None:
            section = (self.phase_view.section.coordinate, self.phase_view.section.value, 1)
        strobe = self.phase_view.strobe_period if poincare else None
        step = self.controls.step_value
        adaptive = self.controls.is_adaptive()
        scene_t_end = float(self.compiled.mechanics.scene.view.get("t_end", 100.0) or 100.0)
        return RunSettings(
            method=method,
            dt=None if adaptive else step,
            tol=step if adaptive else None,
            speed=math.inf if poincare else self.controls.speed,
            t_end=self._section_t_end(scene_t_end) if poincare else math.inf,
            diagnostics=self._wanted_diagnostics(),
            section=section,
            strobe=strobe,
            energy_tolerance=self.energy_tolerance,
        )

    def _section_t_end(self, scene_t_end: float) -> float:
        """Where a section run pauses: 25 scene times (at least ``POINCARE_T_END``), and
        as much again each time Play continues it."""
        return max(POINCARE_T_END, 25 * scene_t_end) * (1 + self._section_continued)

    def _wanted_diagnostics(self) -> tuple[str, ...]:
        wanted = []
        if self._panel_visible("conserved"):
            wanted += ["H", MOMENTA]  # MOMENTA: their range over every step
        drawing = self.compiled is not None and "drawing" in self.compiled.wanted
        if drawing and self._panel_visible("configuration"):
            wanted.append("points")
        return tuple(wanted)

    def _panel_visible(self, key: str) -> bool:
        dock = self.docks.get(key)
        if dock is None:
            return key == "phase"
        if self.isVisible():
            return dock.isVisible()
        return not dock.isHidden()  # rendering without a window on screen (export, tests)

    def _start_system(self, compiled, launches: list[np.ndarray] | None) -> None:
        """Stop the running worker; start a new one on ``compiled`` from the initial state."""
        if self._closed:
            return
        self._stop_worker()
        self.compiled = compiled
        self._generation += 1
        self._section_continued = 0
        self.stop_banner.clear()  # a new run: the last one's stop no longer applies
        n_points = len(compiled.point_names)
        self.store = TrajectoryStore(n_points=n_points)
        y0 = compiled.initial_state()
        self.phase_view.set_system(compiled, y0)
        self.configuration_view.set_system(compiled)
        self.conserved_view.set_system(compiled)
        self.mode_view.set_system(compiled, y0)
        self.constraint_view.set_system(compiled)
        self.chaos_view.set_system(compiled, y0)
        self.orbit_diagram_view.set_system(compiled, y0)
        self.settings = self._current_settings()
        worker = SimulationWorker(compiled, self.settings, self._generation, runs=self._runs)
        worker.blocks_ready.connect(self._on_worker_blocks_ready)
        worker.failed.connect(self._on_worker_failed)
        for state in [y0, *(launches or [])]:
            trajectory = self.store.add(state)
            worker.add_trajectory(trajectory.key, state)
        if not self.controls.playing:
            worker.pause()
            self.builder.frame_shown()  # no motion to draw first: lay out the derivation
        self.runner = WorkerThread(worker)
        self.runner.start()
        self.rate_meter.clear()
        self.method_label.setText("")

    def _stop_worker(self, closing_within: float | None = None) -> None:
        if self.runner is not None:
            if closing_within is None:
                self.runner.stop()
            else:
                self.runner.stop(closing_within)
            self.runner = None

    @property
    def worker(self) -> SimulationWorker | None:
        return None if self.runner is None else self.runner.worker

    def _apply_settings(self) -> None:
        if self.compiled is None or self.worker is None:
            return
        self.settings = self._current_settings()
        self.worker.set_settings(self.settings)

    def _on_worker_blocks_ready(self, frame) -> None:
        if frame.generation != self._generation:
            return  # a late frame from a replaced worker
        for key, block in frame.blocks:
            self.store.append(key, block)
        self.rate_meter.add(time.perf_counter(), frame.steps)
        if frame.steps and self.builder.awaits_frame:
            self._frame_due = True  # told to the builder once the redraw has painted it
        self.frame_received.emit()

    def _on_worker_failed(self, message: str) -> None:
        self.builder.frame_shown()  # no first frame is coming: lay out the derivation
        self.statusBar().showMessage(f"integration failed: {message}", MESSAGE_MS)

    def _on_error_reporter_reported(self, summary: str, details: str) -> None:
        if self._closed:
            return
        self.error_details = details
        self.details_button.setVisible(True)
        self.statusBar().showMessage(f"unexpected error: {summary}", MESSAGE_MS)

    def show_error_details(self) -> QMessageBox:
        """The last unexpected error's traceback, in a (non-modal) message box."""
        box = QMessageBox(self)
        box.setIcon(QMessageBox.Icon.Warning)
        box.setWindowTitle("Unexpected error")
        box.setText(
            "Something went wrong that the program did not expect; the system that was "
            "running keeps running. The traceback below helps to report it."
        )
        box.setDetailedText(self.error_details)
        box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        box.open()
        return box

    def _on_phase_launch_requested(self, state) -> None:
        if self.worker is None:
            return
        t0 = 0.0
        main = self.store.main
        if main is not None and self.compiled.mechanics.classification.time_dependent:
            t0 = main.last_t  # a driven system: start the new orbit at the current time
        trajectory = self.store.add(state, t0)
        self.worker.add_trajectory(trajectory.key, state, t0)

    def _on_phase_launch_refused(self, message: str) -> None:
        self.statusBar().showMessage(message, 5000)

    def _on_phase_mode_changed(self, _mode: str) -> None:
        if self.compiled is not None:
            self._start_system(self.compiled, launches=self._launch_states())

    def _on_controls_method_changed(self, _name) -> None:
        self._apply_settings()

    def _on_controls_notice_posted(self, message: str) -> None:
        self.statusBar().showMessage(message, MESSAGE_MS)

    def _on_controls_step_changed(self, _value) -> None:
        self._apply_settings()

    def _on_controls_speed_changed(self, _speed: float) -> None:
        self._apply_settings()

    def _on_energy_guard_triggered(self) -> None:
        from PySide6.QtWidgets import QInputDialog

        from systems.simulation import parse_energy_tolerance

        current = "off" if self.energy_tolerance is None else f"{self.energy_tolerance:g}"
        text, ok = QInputDialog.getText(
            self,
            "Energy guard",
            "Stop a run whose relative energy error |H - H0|/|H0| exceeds\n"
            "(a number such as 0.01, or off to watch the error grow):",
            text=current,
        )
        if ok:
            try:
                self.set_energy_tolerance(parse_energy_tolerance(text))
            except ValueError as exc:
                self.statusBar().showMessage(str(exc), 8000)

    def set_energy_tolerance(self, value: float | None) -> None:
        """The energy guard for runs from now on (None: off); applies at once. A run that
        had stopped goes on from where it stopped, under the new guard."""
        changed = value != self.energy_tolerance
        stopped = self.run_stopped()
        self.energy_tolerance = value
        self.acted.emit(line("energy-guard", "off" if value is None else float(value)))
        self._show_energy_guard()
        self._apply_settings()
        if stopped and changed and self.worker is not None:
            self._continue_after_stop()

    def _show_energy_guard(self) -> None:
        text = guard_text(self.energy_tolerance)
        self.energy_guard_action.setText(f"Energy guard ({text})…")
        self.stop_banner.set_guard(self.energy_tolerance)

    def run_stopped(self) -> bool:
        """True when the run has nothing left to do: every orbit stopped for a problem
        (``systems.simulation.PROBLEMS``) or reached its end, the main one for a problem."""
        main = self.store.main
        if main is None or main.status in ("running", "ok"):
            return False
        return all(trajectory.finished for trajectory in self.store)

    def _continue_after_stop(self) -> None:
        """The worker restarts its runs from their last states (new settings): they are
        running again, and the play button says so."""
        for trajectory in self.store:
            if trajectory.status != "ok":
                trajectory.status, trajectory.message = "running", ""
        self.stop_banner.clear()
        self._set_play_shown(True)
        self.worker.resume()

    def _set_play_shown(self, playing: bool) -> None:
        """Show the worker's real state on the play button, without a session line."""
        button = self.controls.play_button
        if button.isChecked() != playing:
            button.blockSignals(True)
            button.setChecked(playing)
            button.blockSignals(False)
            self.controls.refresh_play_button()

    def _on_stop_banner_restart_requested(self) -> None:
        self.controls.reset_button.click()  # the same path, and session line, as Reset

    def _on_controls_play_toggled(self, playing: bool) -> None:
        if self.worker is None:
            return
        if playing and self.run_stopped():
            # a run that stopped has nothing to go on with: Play starts it over, as a
            # player at the end of a film (the banner's guard goes on from the stop)
            self._start_system(self.compiled, launches=self._launch_states())
            return
        if playing and self._section_run_ended():
            self._section_continued += 1  # Play continues a section run that reached its end
            self._apply_settings()
        (self.worker.resume if playing else self.worker.pause)()

    def _section_run_ended(self) -> bool:
        main = self.store.main
        return (
            self.phase_view.mode == "poincare"
            and main is not None
            and math.isfinite(self.settings.t_end)
            and main.last_t >= self.settings.t_end * (1 - 1e-12)
        )

    def _on_controls_single_step_requested(self) -> None:
        if self.worker is not None:
            if self.controls.playing:
                self.controls.play_button.setChecked(False)
            self.worker.step()

    def delete_orbit(self, key: int) -> None:
        """Forget one launched orbit (the main orbit, key 0, stays)."""
        if key == 0 or self.worker is None or key not in {t.key for t in self.store}:
            return
        self.acted.emit(line("delete", key))
        self.worker.remove_trajectory(key)
        self.store.remove(key)
        self.store.mark_dirty()

    def _on_controls_reset_requested(self) -> None:
        if self.compiled is not None:
            self._start_system(self.compiled, launches=self._launch_states())

    def _on_controls_clear_requested(self) -> None:
        if self.worker is None:
            return
        for trajectory in list(self.store):
            if trajectory.key != 0:
                self.worker.remove_trajectory(trajectory.key)
                self.store.remove(trajectory.key)

    def _on_dock_visibility_changed(self, _visible: bool) -> None:
        if self.compiled is not None and self.worker is not None:
            wanted = self._wanted_diagnostics()
            if wanted != self.settings.diagnostics:
                self._apply_settings()
            self.store.mark_dirty()

    # -- redraw -------------------------------------------------------------------------------

    def _on_redraw_timer_timeout(self) -> None:
        if self.compiled is None:
            return
        for key, panel in self.panels.items():
            # the work-precision and orbit diagrams draw their own results, not the store's
            refresh = getattr(panel, "refresh", None)
            if refresh is None or not self._panel_visible(key):
                continue
            if self.store.take_dirty(key):
                refresh(self.store)
                if key == "phase":
                    self.panel_refreshes += 1
        if self._frame_due:
            # the builder's layout and numba's start-up hold the GIL for a second or more:
            # they begin once this redraw has been painted, so the motion shows first
            self._frame_due = False
            QTimer.singleShot(FIRST_PAINT_MS, self.builder.frame_shown)
        self.redraws += 1
        self._update_status()

    def _update_status(self) -> None:
        main = self.store.main
        if main is None:
            return
        self.time_label.setText(f"t = {main.last_t:.4g}")
        rate = self.rate_meter.rate(time.perf_counter())
        if self.run_stopped():
            self.rate_label.setText("stopped")  # what ran before the stop is past
        elif rate is None:
            self.rate_label.setText("" if self.controls.playing else "paused")
        else:
            self.rate_label.setText(f"{rate:.3g} steps/s")
            self.rate_label.setToolTip(
                "integrator steps per second of wall time, all orbits together"
            )
        cls = self.compiled.mechanics.classification
        with np.errstate(all="ignore"):
            H = self.compiled.hamiltonian(
                np.array([main.t0, main.last_t]), np.array([main.y0, main.last_y])
            )
        if cls.hamiltonian_conserved:
            error = abs(H[1] - H[0]) / (abs(H[0]) if H[0] != 0 else 1.0)
            self.error_label.setText(f"|ΔH/H₀| = {error:.2e}")
        else:
            self.error_label.setText(f"H = {H[1]:.5g}")
        method = main.method or (self.built.method if self.built else "")
        self.method_label.setText(f"method: {method}")
        self.controls.show_setting_in_use(main.setting, main.setting_value)
        section_end = (self._generation, self._section_continued)
        if self._section_run_ended() and self._section_end_shown != section_end:
            self._section_end_shown = section_end
            self.controls.play_button.setChecked(False)
            self.statusBar().showMessage(
                f"the section run reached t = {main.last_t:.6g}; press Play to go on as long again",
                MESSAGE_MS,
            )
        stopped = main.status not in ("running", "ok")
        stop = (self._generation, main.status, main.message) if stopped else None
        if stop is not None and stop != self._stop_shown:
            # once: closed by the user, it stays closed until the next stop
            self.stop_banner.show_stop(main.status, main.message, self.energy_tolerance)
        self._stop_shown = stop
        if self.controls.playing and self.run_stopped():
            self._set_play_shown(False)  # nothing runs: the button offers Play
            self.worker.pause()

    # -- files ---------------------------------------------------------------------------------

    def _dialog_folder(self) -> str:
        """Where file dialogs start: the open scene's folder, else the last one used."""
        if self.scene_path is not None:
            return str(self.scene_path.parent)
        return self.preferences.folder

    def _on_open_triggered(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "Open scene", self._dialog_folder(), "Scenes (*.toml)"
        )
        if path:
            self.open_file(path)

    def _fill_recent_menu(self) -> None:
        self.recent_menu.clear()
        recent = self.preferences.recent
        for path in recent:
            action = self.recent_menu.addAction(Path(path).name)
            action.setToolTip(path)
            action.setStatusTip(path)
            action.triggered.connect(lambda _=False, p=path: self.open_file(p))
        if not recent:
            self.recent_menu.addAction("(no recent files)").setEnabled(False)
            return
        self.recent_menu.addSeparator()
        self.recent_menu.addAction("Clear the list", self.preferences.clear_recent)

    def _on_save_triggered(self) -> None:
        if self.scene_path is None:
            self._on_save_as_triggered()
        else:
            self.save_scene(self.scene_path)

    def _on_save_as_triggered(self) -> None:
        folder = Path(self._dialog_folder())
        name = self.scene_path.name if self.scene_path else _file_name(self.editor)
        path, _ = QFileDialog.getSaveFileName(
            self, "Save scene as", str(folder / name), "Scenes (*.toml)"
        )
        if path:
            if not path.endswith(".toml"):
                path += ".toml"
            self.save_scene(path)

    def save_scene(self, path: str | Path) -> bool:
        """Write exactly what the editor holds to ``path`` (atomically); True if written.

        A document that does not build is written all the same, with a warning in the
        status bar: typed work is never lost. The file becomes the one Save writes.
        """
        from systems.files import atomic_path

        text = self.editor.document_text()
        try:
            with atomic_path(path) as temporary:
                temporary.write_text(text, encoding="utf-8")
        except OSError as exc:
            self.statusBar().showMessage(f"could not save {path}: {exc.strerror or exc}", 10000)
            return False
        self.acted.emit(line("save", str(path)))
        self.editor.mark_saved()
        self.scene_path = Path(path).resolve()
        self.preferences.add_recent(self.scene_path)
        if self.editor.build_status == "failed":
            self.statusBar().showMessage(
                f"saved {path}, but it does not build yet: {self.editor.build_problem}",
                MESSAGE_MS,
            )
        else:
            self.statusBar().showMessage(f"saved {path}", 5000)
        return True

    def _on_save_session_triggered(self) -> None:
        path, _ = QFileDialog.getSaveFileName(
            self,
            "Save session",
            str(Path(self._dialog_folder()) / "session.session"),
            "Session scripts (*.session);;All files (*)",
        )
        if path:
            self.save_session(path)

    def save_session(self, path: str | Path) -> bool:
        """Write the session script of what was done in this window (docs/sessions.md)."""
        from systems.files import atomic_path

        try:
            with atomic_path(path) as temporary:
                temporary.write_text(self.recorder.text(), encoding="utf-8")
        except OSError as exc:
            self.statusBar().showMessage(f"could not save {path}: {exc.strerror or exc}", 10000)
            return False
        self.statusBar().showMessage(f"saved the session to {path}", 5000)
        return True

    # -- layout, tabs and help ---------------------------------------------------------------

    def reset_layout(self) -> None:
        """View > Reset layout: every dock that applies to the running system back where
        it was when the window opened, at its default share of the window.

        A dock offered only where its panel applies (normal modes, constraint forces)
        comes back where opening the system would show it, and stays hidden otherwise.
        """
        self.presentation_action.setChecked(False)
        self.restoreState(self._default_layout)
        for dock in self.docks.values():
            if dock.isFloating():
                dock.setFloating(False)
            link = getattr(dock.widget(), "link", None)
            dock.setVisible(getattr(link, "wanted", True))
        self.docks["conserved"].raise_()
        self.dock_shares.reset()

    def _build_presentation_menu(self) -> None:
        """View > Presentation (F11) and View > Presentation panels."""
        self.presentation_action = self._action(
            self.view_menu,
            "&Presentation",
            self.presentation.set_active,
            "F11",
            "Full screen, large type and thick curves, only the chosen panels (F11 again: back)",
        )
        self.presentation_action.setCheckable(True)
        panels = self.view_menu.addMenu("Presentation pa&nels")
        panels.setToolTipsVisible(True)
        self.presentation_panel_actions = {}
        for key, dock in self.docks.items():
            action = panels.addAction(dock.windowTitle())
            action.setCheckable(True)
            action.setChecked(key in self.presentation.panels)
            action.toggled.connect(lambda shown, k=key: self.presentation.choose(k, shown))
            self.presentation_panel_actions[key] = action

    def tab_names(self) -> dict[str, QWidget]:
        """What ``show_tab`` accepts: dock keys and the Textbook's and editor's tab names."""
        names: dict[str, QWidget] = dict(self.docks)
        for tabs in self._tab_widgets():
            for index in range(tabs.count()):
                names.setdefault(_slug(tabs.tabText(index)), tabs.widget(index))
        return names

    def _tab_widgets(self) -> list:
        found = [getattr(self.editor, "tabs", None), getattr(self.textbook, "tabs", None)]
        return [tabs for tabs in found if tabs is not None]

    def show_tab(self, name: str) -> None:
        """Bring a dock or a tab (editor, Textbook) to the front by name (``tab_names``).

        Raises ``KeyError`` naming the known names for any other name.
        """
        names = self.tab_names()
        widget = names.get(_slug(name))
        if widget is None:
            raise KeyError(f"no tab {name!r} (tabs: {', '.join(sorted(names))})")
        if isinstance(widget, QDockWidget):
            widget.show()
            widget.raise_()
            return
        for key, tabs in (("editor", self.editor.tabs), ("textbook", self.textbook.tabs)):
            if tabs.indexOf(widget) >= 0:
                self.docks[key].show()
                self.docks[key].raise_()
                tabs.setCurrentWidget(widget)

    def _connect_tabs(self) -> None:
        for tabs in self._tab_widgets():
            tabs.currentChanged.connect(
                lambda index, tabs=tabs: self.acted.emit(line("tab", _slug(tabs.tabText(index))))
            )

    def _show_text(self, title: str, markdown: str) -> QWidget:
        from PySide6.QtWidgets import QDialog, QTextBrowser, QVBoxLayout

        dialog = QDialog(self)
        dialog.setWindowTitle(title)
        browser = QTextBrowser()
        browser.setOpenExternalLinks(True)
        browser.setMarkdown(markdown)
        layout = QVBoxLayout(dialog)
        layout.addWidget(browser)
        dialog.resize(720, 560)
        dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        dialog.show()
        return dialog

    def show_quick_tour(self) -> QWidget:
        """Help > Quick tour: the window's parts and what to do with them."""
        return self._show_text("Quick tour", QUICK_TOUR)

    def show_scene_format(self) -> QWidget:
        """Help > Scene format: docs/scenes.md, rendered."""
        return self._show_text("Scene format", _document("scenes.md"))

    def show_session_format(self) -> QWidget:
        """Help > Session scripts: docs/sessions.md, rendered."""
        return self._show_text("Session scripts", _document("sessions.md"))

    def export_panel_dialog(self, key: str) -> None:
        """File > Export: the format and size (or CSV thinning) first, then the file."""
        from explorer.export_dialog import ExportDialog

        target = self.panels[key].export_target()
        options = ExportDialog.ask(target.size(), self, title=f"Export the {key} view")
        if options is None:
            return
        path, _ = QFileDialog.getSaveFileName(
            self,
            "Export",
            str(Path(self._dialog_folder()) / f"{key}{options.suffix}"),
            options.file_filter,
        )
        if not path:
            return
        try:
            if options.format == "csv":
                self.export_csv(path, every=options.every, points=options.points)
            else:
                self.export_panel(key, path, options.size)
        except (OSError, ValueError) as exc:
            self.statusBar().showMessage(f"could not export {path}: {exc}", 10000)

    def export_panel(self, key: str, path: str | Path, size=None) -> Path:
        """Render a panel to PNG or SVG (chosen by the suffix of ``path``), at ``size``
        (width, height) in pixels; by default twice the panel's size on screen."""
        from explorer.export import export_widget, scaled_size

        panel = self.panels[key]
        if key != "workprecision":
            panel.refresh(self.store)
        target = panel.export_target()
        if size is None:
            size = scaled_size((target.width(), target.height()))
        written = export_widget(target, path, size)
        self.acted.emit(line("export", key, str(path)))
        self.statusBar().showMessage(f"wrote {written}", 5000)
        return written

    def _on_export_csv_triggered(self) -> None:
        from explorer.export_dialog import ExportDialog

        options = ExportDialog.ask(
            self.phase_view.size(), self, formats=("csv",), format="csv", title="Export CSV"
        )
        if options is None:
            return
        path, _ = QFileDialog.getSaveFileName(
            self,
            "Export trajectories",
            str(Path(self._dialog_folder()) / "trajectories.csv"),
            "CSV (*.csv)",
        )
        if path:
            try:
                self.export_csv(path, every=options.every, points=options.points)
            except (OSError, ValueError) as exc:
                self.statusBar().showMessage(f"could not export {path}: {exc}", 10000)

    def export_csv(
        self, path: str | Path, every: int | None = None, points: int | None = None
    ) -> Path:
        """Write every trajectory (t, q, q_dot, p_q, H; an ``orbit`` column) to CSV, every
        ``every``-th row or ``points`` rows evenly in time (default: every row kept)."""
        from explorer.export import write_trajectories_csv

        if self.compiled is None:
            raise RuntimeError("no system is open")
        written = write_trajectories_csv(
            self.compiled, list(self.store), path, every=every, points=points
        )
        self.acted.emit(line("export", "csv", str(path)))
        return written

    # -- closing -------------------------------------------------------------------------------

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt override
        if watched is self and event.type() == QEvent.Type.Close:
            self.shutdown()
        return super().eventFilter(watched, event)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 - Qt override
        self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        """Stop the timers, the builder and the worker threads within ``CLOSE_SECONDS``.

        After ``_closed`` is set a build finishing meanwhile cannot start a new worker. The
        worker is told to abort first, so that it finishes its frame while the builder
        and the Textbook end their worker processes (``systems.processes``); every process
        still working for this window is ended last.
        """
        if self._closed:
            return
        from systems import processes

        deadline = time.monotonic() + CLOSE_SECONDS
        self._closed = True
        self.redraw_timer.stop()
        self.parameter_timer.stop()
        self.editor.shutdown()
        if self.worker is not None:
            self.worker.abort()
        self.builder.stop(max(0.0, deadline - time.monotonic()))
        self.textbook.shutdown()
        self._stop_worker(max(0.05, deadline - time.monotonic()))
        if self.workprecision_view is not None:
            self.workprecision_view.shutdown()
        self.phase_view.map_layer.shutdown()
        self.phase_view.fill_layer.shutdown()
        processes.cancel_all(max(0.05, deadline - time.monotonic()))
        self.collector.stop()
        self.error_reporter.uninstall()


def _slug(text: str) -> str:
    """A tab's name in session scripts: lower case, words joined by hyphens."""
    words = "".join(c if c.isalnum() else " " for c in text.replace("'", "").lower()).split()
    return "-".join(words)


def _file_name(editor) -> str:
    """A file name for Save as from the edited scene's title."""
    title = _slug(editor.title_edit.text() or "scene").replace("-", "_")
    return f"{title or 'scene'}.toml"


def _document(name: str) -> str:
    """A file of ``docs/`` as Markdown (a sentence if this installation lacks it)."""
    path = Path(__file__).resolve().parent.parent / "docs" / name
    try:
        return path.read_text(encoding="utf-8")
    except OSError:
        return f"The document `{name}` is not part of this installation."


QUICK_TOUR = """\
# Phase Explorer: a quick tour

**System editor** (left). Pick a system from the *Catalogue*, or type one: coordinates,
parameters, and either T and V, a Lagrangian L or a Hamiltonian H. Errors show under the
field they are in; nothing you type is lost. *File > New scene* starts a blank one;
*File > Save scene* (Ctrl+S) writes what the editor holds. The *Derivation* tab shows
Lagrange's equations, the momenta, H and Hamilton's equations.

**Phase view** (centre). The orbit in the (q, p) plane of the pair chosen above it, with
the level sets of H where H is conserved. *Click* to launch another orbit from that point;
*right-click* an orbit to delete it. *Poincaré section* (two-degree conservative systems)
plots where orbits cross the section instead; Play continues a section run that paused.

**Configuration** (right). The mechanism moving. **Conserved quantities** (bottom): H and
the conserved momenta over time, and what the run's accuracy costs in the
**Work–precision** tab. **Textbook**: equilibria and normal modes, Hamilton's principle,
reduction, action–angle variables and the energy theorem, computed for this system.

**Toolbar.** *Method* (automatic chooses for the system: the tooltip says why), its step
or tolerance (Enter applies), *Speed*, Play/Pause (Space), single step (Ctrl+.), Reset
(Ctrl+R), Clear orbits (Ctrl+Shift+K).

**Menus.** *File > Export* writes PNG, SVG and CSV. *File > Save session* writes what you
did as a script that `python main.py open --session FILE` replays. *View > Reset layout*
(Ctrl+Shift+L) puts the panels back. *Help > Scene format* documents scene files.
"""
