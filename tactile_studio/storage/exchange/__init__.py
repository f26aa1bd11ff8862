"""Other tools' files, in and out: the importers, the exporters, the ShearSense and XDF formats
and the input files every importer reads. Above the file formats (an import writes session
files, an export reads them).
"""
