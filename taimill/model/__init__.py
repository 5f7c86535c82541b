"""The model as plain data (NumPy and TOML, no Taichi): run parameters and their
validation (`params`), the drive (`drive`), jar geometry as signed distance functions
(`geometry`), the contact-law registry and the NumPy twins of the laws (`laws`) and of
the frame's ramps (`frame`), seeded ball placement (`placement`) and one mill as data
(`spec`). Every other package may import it; it imports none of them."""
