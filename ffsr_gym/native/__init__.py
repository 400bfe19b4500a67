"""The native kernel's Python face (C++17 in ``src/native``, compiled at install into ``ffsr_gym._native``)."""
