"""Qt pieces every workspace uses: the QApplication, the image panel, the job runner, settings, the device panel."""
