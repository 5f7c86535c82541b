"""rerun recordings: the sink writing a `.rrd` (`sink`), its static scene and layout
(`scene`) and the windowed statistics it logs (`stats`)."""
