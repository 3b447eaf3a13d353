import subprocess
import sys


def test_systems_never_imports_qt_or_explorer():
    code = (
        "import sys, systems.scene, systems.mechanics, systems.compiled, systems.expressions\n"
        "qt = ('PySide6', 'pyqtgraph', 'explorer')\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in qt]\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
