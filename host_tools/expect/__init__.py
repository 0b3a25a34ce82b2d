"""Firmware tests: expectation files (``spec``), what a run measured against them
(``evaluate``), running cases (``runner``), JUnit XML (``junit``), timing margins
(``margin``) and the pytest plugin (``pytest_plugin``). User guide: docs/testing.md."""
