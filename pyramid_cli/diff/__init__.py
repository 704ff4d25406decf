"""Golden-image comparison the way OpenImageIO's ``idiff`` does it: statistics, folders of goldens, HTML and
JUnit reports."""
