"""rerun recordings: the sink writing a `.rrd` (`sink`), its static scene and layout
(`scene`) and the windowed statistics it logs (`stats`)."""

import os

# rerun's own log lines (a full disk gives three) would stand beside taimill's one-line
# message, which says the same; they are off unless RUST_LOG asks for them. Set before
# rerun is first imported (its logger reads it then).
os.environ.setdefault("RUST_LOG", "off")
