"""What a finished run says, read back from its folder: its test predictions per trial,
the confusion matrix a researcher explores, two runs compared on the trials they
share, a run re-scored from its saved weights, and the research workspace's index of
session files and run folders. Above experiments (it reads their run folders), below
deploy."""
