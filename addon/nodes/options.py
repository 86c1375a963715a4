"""Shading options: the one declaration the panel and "Assign Shading Model" build from."""
import dataclasses

from ..core.options import Options, option
from .models import MODELS

#: (id, label, description) of every shading model, from the registry (nodes/models).
MODEL_CHOICES = tuple((m.id, m.label, m.description) for m in MODELS)
LIGHT_CHOICES = (("ALL", "All Lights", "Every renderable light of the scene"),
                 ("SELECTED", "Selected Lights", "Only the lights selected together with the meshes"))
ATTENUATION_CHOICES = (("PHYSICAL", "Physical (1/d²)", "Inverse-square law, matches Cycles' own lights"),
                       ("EMPIRICAL", "Empirical", "f_att = min(1/(c1 + c2 d + c3 d²), 1)"))


@dataclasses.dataclass
class ShadingOptions(Options):
    """Which model a material sums over which lights, with which attenuation (REFERENCE.md §1)."""
    model: str = option("PHONG", "Model", "shading model of the new material", choices=MODEL_CHOICES)
    lights: str = option("ALL", "Lights", "lights the material sums over", choices=LIGHT_CHOICES)
    attenuation: str = option("PHYSICAL", "Attenuation", "light falloff with distance", choices=ATTENUATION_CHOICES)
    c1: float = option(1.0, "c1", "constant attenuation", minimum=0.0)
    c2: float = option(0.0, "c2", "linear attenuation", minimum=0.0)
    c3: float = option(1.0, "c3", "quadratic attenuation", minimum=0.0)

    @property
    def coefficients(self):
        return (self.c1, self.c2, self.c3)
