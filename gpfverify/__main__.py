from gpfverify.entry import program

program()
