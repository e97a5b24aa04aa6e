"""One moderngl EGL context, owned by one worker thread.

glcontext makes its EGL context current on creation and releases to *no* context when done, which would
clobber Blender's own GL context on the thread that calls it. So the context lives on a dedicated thread for
the life of the process, and every GPU job is a Python callable run there. Results (numpy arrays) come back
through a Future; progress comes back through a queue that the *calling* thread drains, so RenderEngine
methods are only ever called from Blender's thread.
"""
from __future__ import annotations

import queue
import threading
from concurrent.futures import Future
from typing import Any, Callable


class GpuError(RuntimeError):
    """The GL context could not be created or a GL call failed; the message says why."""


class Cancelled(Exception):
    """Raised inside a job when the caller asked it to stop (RenderEngine.test_break, a newer update)."""


class Job:
    """Handed to every job function: report progress and check for cancellation from the GPU thread."""

    def __init__(self):
        self.events: queue.Queue = queue.Queue()
        self.stop_requested = threading.Event()

    def progress(self, fraction: float, message: str = "") -> None:
        self.events.put((float(fraction), message))

    def check(self) -> None:
        if self.stop_requested.is_set():
            raise Cancelled()


class GpuWorker:
    """The thread that owns the moderngl context. Use `GpuWorker.get()`; never create a context elsewhere."""

    _instance: "GpuWorker | None" = None
    _lock = threading.Lock()

    def __init__(self):
        self._tasks: queue.Queue = queue.Queue()
        self.ctx = None
        self.cache: dict[str, Any] = {}     # long-lived GPU objects (programs), keyed by their source
        self._init_error: BaseException | None = None
        ready = threading.Event()
        self._thread = threading.Thread(target=self._loop, args=(ready,), name="penumbra-gpu", daemon=True)
        self._thread.start()
        ready.wait()
        if self._init_error is not None:
            raise GpuError(f"Penumbra could not create its OpenGL 4.5 context through EGL: {self._init_error}")

    @classmethod
    def get(cls) -> "GpuWorker":
        with cls._lock:
            if cls._instance is None or not cls._instance._thread.is_alive():
                cls._instance = GpuWorker()
            return cls._instance

    def _loop(self, ready: threading.Event) -> None:
        try:
            import moderngl
            self.ctx = moderngl.create_standalone_context(backend="egl", require=450)
        except BaseException as exc:  # report any failure to the creating thread, then end
            self._init_error = exc
            ready.set()
            return
        ready.set()
        while True:
            fn, args, kwargs, future = self._tasks.get()
            if fn is None:
                break
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(fn(self, *args, **kwargs))
            except BaseException as exc:
                future.set_exception(exc)
        self.cache.clear()
        self.ctx.release()

    def submit(self, fn: Callable, *args, **kwargs) -> Future:
        """Queue `fn(worker, *args, **kwargs)` on the GPU thread."""
        future: Future = Future()
        self._tasks.put((fn, args, kwargs, future))
        return future

    def run(self, fn: Callable, *args, on_progress: Callable[[float, str], None] | None = None,
            should_stop: Callable[[], bool] | None = None, poll: float = 0.05, **kwargs):
        """Run `fn(worker, job, *args, **kwargs)` on the GPU thread and wait for it on this thread,
        forwarding progress to `on_progress` and polling `should_stop` while waiting."""
        job = Job()
        future = self.submit(lambda worker: fn(worker, job, *args, **kwargs))
        while True:
            try:
                result = future.result(timeout=poll)
                break
            except TimeoutError:
                pass
            except Exception:
                self._drain(job, on_progress)
                raise
            self._drain(job, on_progress)
            if should_stop is not None and should_stop():
                job.stop_requested.set()
        self._drain(job, on_progress)
        return result

    @staticmethod
    def _drain(job: Job, on_progress) -> None:
        while True:
            try:
                fraction, message = job.events.get_nowait()
            except queue.Empty:
                return
            if on_progress is not None:
                on_progress(fraction, message)
