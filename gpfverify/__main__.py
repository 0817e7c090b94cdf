from gpfverify.cli import program

program()
