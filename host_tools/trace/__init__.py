"""MCAP traces: what a run records and the tools that read it back.

``topics`` names every topic and schema (readers and the writer learn them there);
``protobuf`` holds the message classes and the hand-rolled encoders of the hot ones;
``writer`` is the MCAP writer and ``recorder`` the ``Recorder`` API the simulator calls;
``reader`` opens a finished trace (``Trace``, ``info``); ``run_metadata`` is what a trace
says about its run; ``recover`` salvages a damaged or unfinished one; ``export`` and ``import_csv`` convert to and from other formats.
"""
