"""Placing an upload's files under the locks (:func:`app.store.blobs.commit_all`, issue 16): every file moved into
place has its folder fsynced before the caller's transaction can commit — also when a later file fails to move."""

from __future__ import annotations

import os

import pytest


def test_files_moved_before_a_failure_are_made_durable(tmp_path, monkeypatch):
    import app.store.blobs as blobs

    store = blobs.BlobStore(tmp_path / "blobs")
    writers = [store.sealed(b"first file"), store.sealed(b"second file")]
    synced: list = []
    real_fsync_dir, real_replace = blobs._fsync_dir, os.replace
    moves: list = []

    def replace(src, dst):  # the second move fails, as on a full disk
        moves.append(dst)
        if len(moves) == 2:
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(blobs, "_fsync_dir", lambda folder: synced.append(folder) or real_fsync_dir(folder))
    monkeypatch.setattr(blobs.os, "replace", replace)
    with pytest.raises(OSError, match="No space"):
        blobs.commit_all(writers)
    first = store.path(writers[0].sha256)
    assert first.is_file() and synced == [first.parent]  # before: moved, its folder never fsynced
    for w in writers:
        w.discard()


def test_each_receiving_folder_is_fsynced_once_and_stored_content_is_not_moved_again(tmp_path, monkeypatch):
    import app.store.blobs as blobs

    store = blobs.BlobStore(tmp_path / "blobs")
    synced: list = []
    real = blobs._fsync_dir
    monkeypatch.setattr(blobs, "_fsync_dir", lambda folder: synced.append(folder) or real(folder))
    datas = [f"file {i}".encode() for i in range(12)]
    digests = blobs.commit_all([store.sealed(d) for d in datas])
    assert [store.read(d) for d in digests] == datas
    folders = {store.path(d).parent for d in digests}
    assert sorted(synced) == sorted(folders)
    synced.clear()
    again = blobs.commit_all([store.sealed(d) for d in datas])  # the same content: found stored, intact
    assert again == digests and synced == []
