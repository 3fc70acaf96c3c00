"""Helpers the Qt-free model tests share: a job runner the test turns by hand, and settings in a dict."""

from flexvox_app.gui.models.jobs import Cancelled, CancelToken


class Handle:
    """A job's handle as JobRunner's: a name, a cancel token, the outcome."""

    def __init__(self, name):
        self.name = name
        self.token = CancelToken()
        self.outcome = None
        self.running = True
        self.result = None

    def cancel(self):
        self.token.cancel()


class TurnedRunner:
    """Jobs wait in a list; :meth:`turn` runs them one by one on this thread, then their callbacks."""

    def __init__(self):
        self.waiting = []
        self.handles = []
        """Every handle submitted, in order."""

    def submit(self, name, fn, *, on_progress=None, on_finished=None, on_failed=None, on_cancelled=None,
               on_done=None):
        handle = Handle(name)
        self.handles.append(handle)
        self.waiting.append((handle, fn, on_progress, on_finished, on_failed, on_cancelled, on_done))
        return handle

    def names(self):
        return [job[0].name for job in self.waiting]

    def turn(self, only=None):
        """Run the jobs waiting (those named ``only``; the others are dropped), and those they submit."""
        while self.waiting:
            handle, fn, on_progress, on_finished, on_failed, on_cancelled, on_done = self.waiting.pop(0)
            if only is not None and handle.name not in only:
                continue
            try:
                handle.result = fn(handle.token, on_progress or (lambda done, total: None))
            except Cancelled:
                handle.outcome = "cancelled"
                if on_cancelled:
                    on_cancelled()
            except Exception as exc:  # noqa: BLE001 - as the job runner: every failure reported in words
                handle.outcome = "failed"
                if on_failed:
                    on_failed(str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}")
            else:
                handle.outcome = "finished"
                if on_finished:
                    on_finished(handle.result)
            handle.running = False
            if on_done:
                on_done()


class Settings(dict):
    """Settings kept in a dict, with the methods the models call on AppSettings."""

    def get_str(self, key, default=""):
        return self.get(key, default)

    get_int = get_bool = get_str

    def set(self, key, value):
        self[key] = value

    def remember_folder(self, path, key=""):
        self[key or "files/last_folder"] = str(path)


def without_ground_truth(recording, folder):
    """A copy of ``recording`` in ``folder`` without its ground truth, as a captured recording is; its path."""
    import shutil
    from pathlib import Path

    copy = Path(folder) / f"{Path(recording).stem}-captured.zarr"
    shutil.copytree(recording, copy)
    for name in ("ground_truth", "ground_truth_crc"):
        shutil.rmtree(copy / name)
    return copy


class QueuedRunner:
    """As the Qt job runner behaves at its worst: the worker runs to its end at once, and its ``finished`` waits in
    the GUI thread's queue (the handle still running) until :meth:`deliver`."""

    def __init__(self):
        self.queue = []

    def submit(self, name, fn, *, on_progress=None, on_finished=None, on_failed=None, on_cancelled=None,
               on_done=None):
        handle = Handle(name)
        result = fn(handle.token, lambda done, total: None)
        self.queue.append(lambda: on_finished and on_finished(result))
        return handle

    def deliver(self):
        queue, self.queue = self.queue, []
        for callback in queue:
            callback()
