"""What every area's benchmark returns."""
from dataclasses import dataclass, field


@dataclass
class BenchResult:
    """Tables ({name: [row dicts]}, each also a CSV), chart paths (PNG) and named figures of one area."""
    tables: dict = field(default_factory=dict)
    charts: list = field(default_factory=list)
    figures: dict = field(default_factory=dict)

    def merge(self, other):
        """Append ``other``'s tables, charts and figures (in their order) to this result; return self."""
        self.tables.update(other.tables)
        self.charts.extend(other.charts)
        self.figures.update(other.figures)
        return self
