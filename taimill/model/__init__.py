"""The model as plain data (NumPy and TOML, no Taichi). Run parameters and their
validation, by job: checked reading of TOML tables (`tables`), materials, friction pairs
and the ball charge (`materials`), jars (`jars`), contact sets and their calibrated
normal laws (`contact_sets`), given start positions (`positions`), the preset that
assembles them (`preset`) and the rule book it shares with the live mill (`rules`);
also the drive (`drive`), allowed ranges (`ranges`), jar geometry as signed distance
functions (`geometry`), the contact-law registry and the NumPy twins of the laws
(`laws`) and of the frame's ramps (`frame`), seeded ball placement (`placement`) and
one mill as data (`spec`). Every other package may import it; it imports none of them."""
