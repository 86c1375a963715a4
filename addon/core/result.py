"""What every job returns (bake, shadows, SSAO, environment map, radiosity, demo)."""
import collections.abc
import dataclasses


@dataclasses.dataclass
class JobResult(collections.abc.Mapping):
    """A job's outcome. Reading it as a mapping reads ``report``, the content of the JSON report the job
    wrote (the file format of DESIGN.md); ``path`` is that file, ``summary`` one line for a person,
    ``arrays`` in-memory results for the UI or a caller that are not in the JSON (images, solutions)."""
    report: dict
    path: str = None
    summary: str = ""
    arrays: dict = dataclasses.field(default_factory=dict)

    def __getitem__(self, key):
        return self.report[key]

    def __iter__(self):
        return iter(self.report)

    def __len__(self):
        return len(self.report)
