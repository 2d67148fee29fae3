"""Regenerate the committed ``mjcf/neck3x.xml``: ``python -m neck_sim.mjcf``."""

from neck_sim.mjcf.build import committed_xml_path, write_xml
from neck_sim.params import default_params

write_xml(default_params(3), committed_xml_path())
print(f"wrote {committed_xml_path()}")
