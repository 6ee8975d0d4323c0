"""Error types shared by every evoscen package."""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input (config, map, bag, data file, CLI argument).

    The message is one line naming the file, the key or element (and line),
    the offending value and what is allowed. Command-line tools print it as
    ``error: <message>`` and exit with status 2.
    """


class HostFault(RuntimeError):
    """An output of the run could not be written: the disk is full, the output directory became
    read-only or vanished (docs/recording.md, "Faults of the host").

    Not the user's input nor the simulation's fault: the run stops at the next step boundary and
    command-line tools print :meth:`line` (one line) and exit with status 5
    (:data:`evoscen_contract.contract.EXIT_HOST_FAULT`).

    ``path``: the file that could not be written; ``cause``: the operating system's reason;
    ``bag_dir``: the run's bag (None if it records none); ``bag_state``: ``"finished"`` (the bag
    was closed with every step written before the fault), ``"reindex"`` (it holds them but could
    not be finished: ``scripts/reindex.py`` finishes it), ``"lost"`` (its file is gone) or None
    (not known yet); ``steps``: world states in the bag.
    """

    def __init__(self, message: str, *, path=None, cause: str = "", errno: int | None = None,
                 bag_dir=None, bag_state: str | None = None, steps: int | None = None) -> None:
        super().__init__(message)
        self.path = path
        self.cause = cause
        self.errno = errno
        self.bag_dir = bag_dir
        self.bag_state = bag_state
        self.steps = steps

    #: errno values that are the host's, not the user's: a full disk or quota, a read-only file
    #: system, an I/O error, a file too large for the file system.
    ERRNOS = frozenset({28, 122, 30, 5, 27})  # ENOSPC, EDQUOT, EROFS, EIO, EFBIG

    @classmethod
    def of(cls, exc: OSError, path, **kw) -> HostFault:
        """The fault of an operating-system error ``exc`` writing ``path``."""
        import errno as errnos

        name = errnos.errorcode.get(exc.errno or 0)
        cause = (exc.strerror or str(exc)) + (f" ({name})" if name else "")
        return cls(f"cannot write {path}: {cause}", path=path, cause=cause, errno=exc.errno, **kw)

    def line(self) -> str:
        """One line: which file, why, what became of the bag and what to do."""
        what = f"cannot write {self.path}: {self.cause}"
        fix = "free space on the disk (or make the output directory writable)"
        steps = "" if self.steps is None else f" the {self.steps} world states recorded before it,"
        if self.bag_dir is None:
            return f"{what}; {fix}, then run again"
        if self.bag_state == "finished":
            return f"{what}; the bag {self.bag_dir} is finished, with{steps} readable as it is; {fix}, then run again"
        if self.bag_state == "empty":
            return f"{what}; the bag {self.bag_dir} holds no step (the first second did not fit); {fix}, then run again"
        if self.bag_state == "lost":
            return f"{what}; the bag {self.bag_dir} is gone (its directory was removed); {fix}, then run again"
        return (f"{what}; the bag {self.bag_dir} holds{steps} but could not be finished; {fix}, then run: "
                f"python scripts/reindex.py {self.bag_dir}")


class PluginFault(RuntimeError):
    """A driver model (a plug-in or a built-in) raised an exception while it was built or asked for
    commands (docs/plugins.md §3, docs/recording.md).

    The message is one line naming the model, its role, what it was doing (``act() at step 12``,
    ``its factory``), the exception's type and message and the file and line in the model's code
    where it was raised. The run ends there: in-process the bag is finished (``run_end`` of kind
    ``aborted``), in the graph the controller prints the same ``error: <message>`` and exits, and the
    simulation aborts the run at once. Command-line tools print ``error: <message>`` and exit with
    status 3 (:data:`evoscen_contract.contract.EXIT_FAULT`, a controller fault), no traceback.

    ``model``, ``role``: the model's name and role; ``step``: the step at which ``act`` raised (None
    for the factory); ``bag_dir``, ``steps``: the run's finished bag and its world states (set by the
    in-process runner; None otherwise).
    """

    def __init__(self, message: str, *, model: str, role: str, step: int | None = None) -> None:
        super().__init__(message)
        self.model = model
        self.role = role
        self.step = step
        self.bag_dir = None
        self.steps: int | None = None
