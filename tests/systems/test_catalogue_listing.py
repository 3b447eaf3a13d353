"""The catalogue's listing: each scene file read once, again only when it changes."""

from __future__ import annotations

import systems.scene as scene_module
from systems.scene import catalogue


def test_the_catalogue_reads_a_file_again_only_when_it_changes(tmp_path, monkeypatch):
    monkeypatch.setattr(scene_module, "SCENES_DIR", tmp_path)
    read = []
    entry_of = scene_module._catalogue_entry

    def counted(path):
        read.append(path.name)
        return entry_of(path)

    monkeypatch.setattr(scene_module, "_catalogue_entry", counted)
    (tmp_path / "b.toml").write_text('title = "Bee"\ndescription = "buzz"\n')
    (tmp_path / "a.toml").write_text('title = "Ay"\n')
    (tmp_path / "c.toml").write_text("title = [not toml\n")
    first = catalogue()
    assert [(e.name, e.title, e.description) for e in first] == [
        ("a", "Ay", ""),
        ("b", "Bee", "buzz"),
    ]
    assert sorted(read) == ["a.toml", "b.toml", "c.toml"]
    read.clear()
    assert catalogue() == first
    assert read == ["c.toml"]  # only the file that did not read is tried again
    read.clear()
    (tmp_path / "b.toml").write_text('title = "Bumblebee"\n')
    (tmp_path / "c.toml").write_text('title = "Sea"\n')
    assert [e.title for e in catalogue()] == ["Ay", "Bumblebee", "Sea"]
    assert sorted(read) == ["b.toml", "c.toml"]
